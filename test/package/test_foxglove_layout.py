"""
doc/foxglove/leadscrew_axis.json is a valid Foxglove layout for the node's topics.

The layout format (Foxglove's exported layouts): ``configById`` (panel id
``Type!name`` -> its config), ``layout`` (a tree of splits with ``first``,
``second``, ``direction`` row/column and ``splitPercentage`` 0-100, whose
leaves are panel ids), ``globalVariables``, ``userNodes``, ``playbackConfig``.
Every message path must name a topic the node serves and a field of that
topic's type, resolved with rosbags' type store (ThreadState: its ros2msg
text parsed by rosbags).
"""
import json
import re

from helpers import REPO
from leadscrew_sim.io.msgdefs import EMBEDDED
from leadscrew_sim.io.run_file import DESCRIPTION_TOPICS
from leadscrew_sim.io.topics import resolve, TOPIC_SPECS
import pytest
from rosbags.typesys import get_types_from_msg, Stores, get_typestore

LAYOUT = REPO / 'doc' / 'foxglove' / 'leadscrew_axis.json'
PANEL_TYPES = {'Plot', 'StateTransitions', '3D', 'DiagnosticSummary', 'DiagnosticStatusPanel',
               'Publish', 'Parameters', 'RawMessages'}
PRIMITIVE = {'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16', 'uint16',
             'int32', 'uint32', 'int64', 'uint64', 'string'}


@pytest.fixture(scope='module')
def layout():
    """Return the parsed layout."""
    return json.loads(LAYOUT.read_text())


@pytest.fixture(scope='module')
def store():
    """Return rosbags' Jazzy type store with ThreadState added."""
    ts = get_typestore(Stores.ROS2_JAZZY)
    name = 'leadscrew_sim/msg/ThreadState'
    ts.register(get_types_from_msg(EMBEDDED[name], name))
    return ts


def served_topics():
    """Return {topic: type} the node serves in the root namespace."""
    topics = {resolve(t): typ for t, (typ, role, _q) in TOPIC_SPECS.items() if role != 'clock'}
    topics.update({resolve(rel): typ for rel, typ, _q in DESCRIPTION_TOPICS.values()})
    return topics


def leaves(node):
    """Yield the panel ids of a layout tree, checking each split."""
    if isinstance(node, str):
        yield node
        return
    assert node['direction'] in ('row', 'column'), node
    assert 0 <= node.get('splitPercentage', 50) <= 100, node
    yield from leaves(node['first'])
    yield from leaves(node['second'])


def field_type(store, type_name, path):
    """Return the type of a field path (``a.b[1].c``) of a message type, or fail."""
    for part in path.split('.'):
        m = re.fullmatch(r'([A-Za-z_][A-Za-z0-9_]*)(\[\d+\])?', part)
        assert m, (type_name, path)
        fields = dict(store.fielddefs[type_name][1])
        assert m.group(1) in fields, (type_name, m.group(1), sorted(fields))
        kind, spec = fields[m.group(1)]
        if m.group(2):              # an element of a sequence or an array
            assert kind.name in ('SEQUENCE', 'ARRAY'), (type_name, part)
            kind, spec = spec[0]
        type_name = spec if kind.name == 'NAME' else spec[0]
    return type_name


def test_layout_structure(layout):
    assert set(layout) >= {'configById', 'layout', 'globalVariables', 'userNodes',
                           'playbackConfig'}
    ids = list(leaves(layout['layout']))
    assert len(ids) == len(set(ids))
    assert set(ids) == set(layout['configById']), set(ids) ^ set(layout['configById'])
    for pid in ids:
        assert pid.split('!')[0] in PANEL_TYPES, pid


def test_layout_paths_name_served_topics_and_fields(layout, store):
    topics = served_topics()
    plotted = set()
    for pid, cfg in layout['configById'].items():
        kind = pid.split('!')[0]
        for series in cfg.get('paths', ()):
            topic, _, path = series['value'].partition('.')
            assert topic in topics, (pid, topic)
            leaf = field_type(store, topics[topic], path)
            assert leaf in PRIMITIVE and leaf != 'string', (pid, series['value'], leaf)
            assert series['timestampMethod'] in ('receiveTime', 'headerStamp')
            if series['timestampMethod'] == 'headerStamp':
                assert 'header' in dict(store.fielddefs[topics[topic]][1]), series
            plotted.add(series['value'])
        if kind in ('DiagnosticSummary', 'DiagnosticStatusPanel'):
            assert topics[cfg['topicToRender']] == 'diagnostic_msgs/msg/DiagnosticArray'
        if kind == 'Publish':
            assert topics[cfg['topicName']] == cfg['datatype']
            json.loads(cfg['value'])
        if kind == '3D':
            assert topics['/axis/robot_description'] == 'std_msgs/msg/String'
            assert '/axis/robot_description' in cfg['topics'], cfg['topics']
            assert set(cfg['topics']) <= set(topics)
    # What the issue asks the layout to show.
    for value in ('/axis/joint_states.position[1]', '/axis/joint_states.velocity[1]',
                  '/axis/joint_states.effort[0]', '/thread_force.wrench.force.x',
                  '/sim/thread_state.stick_a', '/sim/thread_state.contact_a'):
        assert value in plotted, value
