"""
``identify`` of a still recording: a parameter that does not act is never written.

``simulate --duration 2`` of the default preset commands nothing: the nut only
settles within its contact compliance under the payload's weight (nanometres).
No friction law shows in that: the thread never slides, the screw never turns
and the nut never moves by more than a micron. Oracles: the recording itself,
read with mcap_ros2 (a reader we did not write), shows the nut's travel, and
the parameter file must then hold no fitted value at all, exact data or not
(a fit on exact data finds values such as 1e-12 N m for them, which mean nothing).
"""
from helpers import cli_ok
from mcap_ros2.reader import read_ros2_messages
import yaml


def test_a_still_recording_writes_no_parameter(tmp_path):
    """Nothing moved: every default parameter is 'not identifiable' and none is written."""
    run = tmp_path / 'still.mcap'
    cli_ok('simulate', '--duration', '2', '-o', run)
    nut = [m.ros_msg.position[1] for m in read_ros2_messages(str(run),
                                                             topics=['/axis/joint_states'])]
    assert len(nut) == 2000 and max(nut) - min(nut) < 1e-6     # the oracle: nothing moved
    out = tmp_path / 'still.yaml'
    r = cli_ok('identify', run, '--output-params', out)
    params = yaml.safe_load(out.read_text())['/**']['ros__parameters']
    assert set(params) == {'preset'}, params
    for name in ('bearing_coulomb', 'guide_coulomb'):
        line, = [ln for ln in r.stdout.splitlines() if ln.strip().startswith(f'{name}:')]
        assert 'not identifiable' in line and 'never' in line, line
    assert 'determined by exact data' not in out.read_text()
