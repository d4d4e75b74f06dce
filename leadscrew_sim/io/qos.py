"""QoS profiles as rosbag2 writes them into ``offered_qos_profiles`` channel metadata (YAML)."""
from ..core import yamlio

DURATION_INFINITE = {'sec': 9223372036, 'nsec': 854775807}

_QOS_CHOICES = {
    'history': ('keep_last', 'keep_all', 'system_default', 'unknown'),
    'reliability': ('reliable', 'best_effort', 'system_default', 'unknown'),
    'durability': ('volatile', 'transient_local', 'system_default', 'unknown'),
    'liveliness': ('automatic', 'manual_by_topic', 'system_default', 'unknown'),
}


def dump_yaml(value):
    return yamlio.dump(value)


def qos_list(qos):
    try:
        profiles = yamlio.load(qos)
    except yamlio.YAMLError:
        return []
    return profiles if isinstance(profiles, list) else []


def qos_profile_yaml(*, reliability='reliable', durability='volatile', history='keep_last',
                     depth=10, liveliness='automatic'):
    """
    Return an ``offered_qos_profiles`` string for one publisher, as rosbag2 writes it.

    The form is the YAML sequence rosbag2_storage serializes (metadata version 9:
    policy names as strings; deadline, lifespan and liveliness lease as
    ``{sec, nsec}``, here infinite). ``depth`` is the history depth in messages.
    """
    profile = {'history': history, 'depth': int(depth), 'reliability': reliability,
               'durability': durability, 'deadline': dict(DURATION_INFINITE),
               'lifespan': dict(DURATION_INFINITE), 'liveliness': liveliness,
               'liveliness_lease_duration': dict(DURATION_INFINITE),
               'avoid_ros_namespace_conventions': False}
    for key, allowed in _QOS_CHOICES.items():
        if profile[key] not in allowed:
            raise ValueError(f'QoS {key} must be one of {allowed}, not {profile[key]!r}')
    return dump_yaml([profile])


DEFAULT_QOS = qos_profile_yaml()
