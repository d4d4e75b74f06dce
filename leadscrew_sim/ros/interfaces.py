"""rclpy types of the topic table: QoS profiles and message classes from their names."""
import importlib

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

__all__ = ['message_class', 'qos_profile']


def qos_profile(spec):
    """Return the rclpy QoSProfile of a QoS dict of :data:`leadscrew_sim.io.topics.TOPIC_SPECS`."""
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=spec['depth'],
                      reliability=ReliabilityPolicy[spec['reliability'].upper()],
                      durability=DurabilityPolicy[spec['durability'].upper()])


def message_class(type_name):
    """Return the message class of a type name such as ``'std_msgs/msg/Float64'``."""
    package, kind, name = type_name.split('/')
    return getattr(importlib.import_module(f'{package}.{kind}'), name)
