"""
The robot description of the node: the URDF of the axis, its transforms, their publishers.

Recordings always carry ``robot_description``, ``/tf_static`` and ``/tf``;
with ``publish_tf`` the node also publishes them (``/tf`` and ``/tf_static``
only where tf2_msgs is installed: its Python message class is needed to
create the publishers).
"""
from ..io import tf as TF
from ..io.description import DescriptionError, JointTree, render_urdf, xacro_args
from ..io.qos import qos_profile_yaml
from ..io.run_file import DESCRIPTION_TOPICS
from .interfaces import message_class, qos_profile

__all__ = ['RobotDescription']


class RobotDescription:
    """
    The URDF, its joint tree and TF encoder, and (with publish_tf) the publishers.

    Parameters
    ----------
    node : rclpy.node.Node
        The node (names, publishers, logger).
    urdf : str
        The rendered URDF.
    publish : bool
        Create publishers (the parameter publish_tf).

    """

    def __init__(self, node, urdf, publish):
        """Parse the URDF; create the publishers if asked."""
        self.urdf = urdf
        self.tree = JointTree(urdf)
        self.tf = TF.TfEncoder(self.tree.moving_frames)
        #: key of DESCRIPTION_TOPICS -> resolved topic name
        self.topics = {key: node.resolve_topic_name(rel)
                       for key, (rel, _t, _q) in DESCRIPTION_TOPICS.items()}
        self.pubs = {}
        for key, (rel, type_name, qos) in (DESCRIPTION_TOPICS.items() if publish else ()):
            try:
                msg_type = message_class(type_name)
            except ImportError:
                node.get_logger().warn(f'publish_tf: {type_name} is not installed; {rel} is '
                                       'recorded but not published')
                continue
            self.pubs[key] = node.create_publisher(msg_type, rel, qos_profile(qos))

    @classmethod
    def make(cls, node, params, joint_prefix, publish):
        """
        Return the description of the axis of ``params``, or None (with a warning) if none.

        Parameters
        ----------
        node : rclpy.node.Node
            The node.
        params : ScrewParams
            The axis (lead, hand, backlash, stroke, ...).
        joint_prefix : str
            Prefix of the joint and link names.
        publish : bool
            The parameter publish_tf.

        """
        try:
            return cls(node, render_urdf(xacro_args(params, joint_prefix)), publish)
        except (DescriptionError, ValueError) as exc:
            node.get_logger().warn(f'no robot description (TF not published or recorded): '
                                   f'{exc}')
            return None

    def channels(self):
        """Return {resolved topic: (type name, offered QoS yaml, trim)} of the recording."""
        return {self.topics[key]: (type_name, qos_profile_yaml(**qos), False)
                for key, (_rel, type_name, qos) in DESCRIPTION_TOPICS.items()}

    def publish_static(self, stamp_ns, recorder):
        """Publish (with publish_tf) robot_description and /tf_static; record them if given."""
        static = [(stamp_ns, p, c, t, r) for p, c, t, r in self.tree.static_transforms()]
        for key, data in (('robot_description', TF.encode_string(self.urdf)),
                          ('/tf_static', TF.encode_tf_message(static))):
            if key in self.pubs:
                self.pubs[key].publish(data)
            if recorder is not None and recorder.active:
                recorder.write(self.topics[key], data, stamp_ns)

    def publish_tf(self, stamp_ns, screw_angle, nut_position, recorder, publish=True):
        """Publish (with publish_tf, unless ``publish`` is False) and record one tick's /tf."""
        pub = self.pubs.get('/tf') if publish else None
        if pub is None and not recorder.active:
            return
        data = self.tf(stamp_ns, self.tree.moving_values(screw_angle, nut_position))
        if pub is not None:
            pub.publish(data)
        if recorder.active:
            recorder.write(self.topics['/tf'], data, stamp_ns)
