"""
The servo drive's mode and fault codes, with their names (doc/model.md section 16).

The codes are what a command row's mode field, the drive's state and its
outputs hold; the compiled drive (:mod:`.engine.drive`) and the kernel read
them from here. Plain Python: importing this module compiles nothing.
"""

MODE_TORQUE = 0         #: cyclic synchronous torque: the command torque
MODE_VELOCITY = 1       #: cyclic synchronous velocity: w_ref = the command rate
MODE_POSITION = 2       #: cyclic synchronous position: P loop on the angle
MODE_QUICKSTOP = 3      #: ramp to standstill, then hold the position (ends in MODE_POSITION)

#: Mode code -> name.
MODE_NAMES = {MODE_TORQUE: 'torque', MODE_VELOCITY: 'velocity', MODE_POSITION: 'position',
              MODE_QUICKSTOP: 'quick_stop'}

FAULT_NONE = 0              #: no fault
FAULT_FOLLOWING_ERROR = 1   #: |q_ref - q_fb| above following_error_limit in position mode
FAULT_TORQUE_LIMIT = 2      #: velocity loop output at +-max_torque longer than torque_limit_time
FAULT_INJECTED = 3          #: latched on request (fault injection)
FAULT_OVERSPEED = 4         #: |motor rate| above OVERSPEED_MARGIN * max_screw_velocity, any mode

#: Fault code -> name.
FAULT_NAMES = {FAULT_NONE: 'none', FAULT_FOLLOWING_ERROR: 'following_error',
               FAULT_TORQUE_LIMIT: 'torque_limit', FAULT_INJECTED: 'injected',
               FAULT_OVERSPEED: 'overspeed'}

#: The overspeed fault trips at this multiple of the rated speed max_screw_velocity: the
#: margin a servo drive leaves above its rated speed for the loops' overshoot.
OVERSPEED_MARGIN = 1.2


def mode_code(mode):
    """
    Return the MODE_* code of a mode code or name; raise ValueError otherwise.

    Parameters
    ----------
    mode : int or str
        A MODE_* code or its name in :data:`MODE_NAMES`.

    """
    if isinstance(mode, str):
        for code, name in MODE_NAMES.items():
            if name == mode:
                return code
        raise ValueError(f'unknown drive mode {mode!r} (known: {", ".join(MODE_NAMES.values())})')
    if isinstance(mode, bool) or mode not in MODE_NAMES:
        raise ValueError(f'unknown drive mode {mode!r} (codes: {sorted(MODE_NAMES)})')
    return int(mode)
