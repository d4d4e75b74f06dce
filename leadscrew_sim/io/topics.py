"""
The topic table: every topic of the node with its type, role and QoS.

The node creates its publishers and subscriptions from it, and the offline
tools write and find the same channels in MCAP files.
"""

#: QoS of every command and state topic: reliable, volatile, keep last 10
#: (joint_state_broadcaster convention: best-effort and reliable subscribers connect).
RELIABLE_10 = dict(reliability='reliable', durability='volatile', depth=10)

#: QoS of the switch topics: reliable, transient local, depth 1 (a late subscriber
#: gets the current state at once).
LATCHED_1 = dict(reliability='reliable', durability='transient_local', depth=1)

#: Relative topic name -> (message type, role, QoS). '/clock' is absolute, as the
#: node publishes it.
TOPIC_SPECS = {
    'torque_command': ('std_msgs/msg/Float64', 'command', RELIABLE_10),
    'joint_commands': ('sensor_msgs/msg/JointState', 'command', RELIABLE_10),
    'external_force': ('std_msgs/msg/Float64', 'command', RELIABLE_10),
    'velocity_command': ('std_msgs/msg/Float64', 'command', RELIABLE_10),
    'position_command': ('std_msgs/msg/Float64', 'command', RELIABLE_10),
    'joint_states': ('sensor_msgs/msg/JointState', 'state', RELIABLE_10),
    'nut_position': ('std_msgs/msg/Float64', 'state', RELIABLE_10),
    'thread_force': ('geometry_msgs/msg/WrenchStamped', 'state', RELIABLE_10),
    'sim/joint_states': ('sensor_msgs/msg/JointState', 'state', RELIABLE_10),
    'sim/thread_state': ('leadscrew_sim/msg/ThreadState', 'record', RELIABLE_10),
    'sim/ageing': ('leadscrew_sim/msg/AgeingState', 'record', RELIABLE_10),
    'diagnostics': ('diagnostic_msgs/msg/DiagnosticArray', 'diagnostics', RELIABLE_10),
    'limit_switch/min': ('std_msgs/msg/Bool', 'switch', LATCHED_1),
    'limit_switch/max': ('std_msgs/msg/Bool', 'switch', LATCHED_1),
    'home_switch': ('std_msgs/msg/Bool', 'switch', LATCHED_1),
    '/clock': ('rosgraph_msgs/msg/Clock', 'clock', RELIABLE_10),
}

#: The name on the ROS graph of a topic whose table key differs from it: the node's
#: JointState pair and its robot description live under ``axis/``, so that a
#: joint_state_broadcaster (``/joint_states``) and a controller_manager
#: (``/robot_description``) in the same namespace never share a topic with the node.
GRAPH_NAMES = {'joint_states': 'axis/joint_states', 'joint_commands': 'axis/joint_commands',
               'robot_description': 'axis/robot_description'}


def graph_name(topic):
    """Return the relative name on the graph of the topic table's (or the description's) key."""
    return GRAPH_NAMES.get(topic, topic)


#: The switch topics, in the order of the model's switch states (min, max, home).
SWITCH_TOPICS = tuple(t for t, (_typ, role, _q) in TOPIC_SPECS.items() if role == 'switch')

#: Topics in the order the node registers its recording channels.
COMMAND_TOPICS = tuple(t for t, (_typ, role, _q) in TOPIC_SPECS.items() if role == 'command')
STATE_TOPICS = tuple(t for t, (_typ, role, _q) in TOPIC_SPECS.items() if role == 'state')
#: Topics that are recorded but not published: the thread contact and energy of every tick.
RECORD_TOPICS = tuple(t for t, (_typ, role, _q) in TOPIC_SPECS.items() if role == 'record')


def resolve(topic, namespace='/'):
    """Return the resolved graph name of a topic key (:func:`graph_name`) in ``namespace``."""
    topic = graph_name(topic)
    if topic.startswith('/'):
        return topic
    ns = namespace.rstrip('/')
    return f'{ns}/{topic}'
