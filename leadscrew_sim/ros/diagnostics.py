"""The node's once-a-second ``diagnostics``: the axis, its loop and its recording."""
from builtin_interfaces.msg import Time as TimeMsg
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

from ..core import geometry

NS = 1_000_000_000

__all__ = ['diagnostic_array', 'live_view_values', 'LOST_STEPS_KEY', 'stamp_msg', 'stepper_values']


def stamp_msg(stamp_ns):
    """Return the builtin_interfaces/Time of an integer nanosecond time."""
    sec, nsec = divmod(int(stamp_ns), NS)
    return TimeMsg(sec=sec, nanosec=nsec)


def _us(ns):
    return '' if ns is None else f'{ns / 1000.0:.1f}'


def diagnostic_array(*, name, preset, params, model, clock_mode, sim_time_ns, target_rate,
                     command_age, stale, loop, lateness, counts, recorder, dropped=(0, 0),
                     live=None, far_commands=0):
    """
    Return the DiagnosticArray of one window.

    Parameters
    ----------
    name, preset : str
        Node name and preset (the status name and hardware id).
    params, model : ScrewParams, LeadScrewModel
        The physics and its current state.
    clock_mode : str
        Clock mode of the node.
    sim_time_ns : int
        Current sim time (also the header stamp).
    target_rate : float
        update_rate [Hz].
    command_age : str
        Age of the last drive command [s], formatted, or ``'no command yet'``.
    stale : bool
        The command is stale (torque mode: 0 N m applied; else a quick stop).
    loop : leadscrew_sim.ros.timing.LoopStats
        Loop counters, ``achieved_rate`` of the window just closed.
    lateness : dict
        Lateness percentiles of that window [ns] (``p50``, ``p99``, ``max``).
    counts : tuple of int
        (commands, rejected commands, ignored commands).
    recorder : leadscrew_sim.io.recorder.Recorder
        The recorder (``status()``, ``active``, ``dropped``).
    dropped : tuple of int
        (commands, state samples) lost to the injected drop rates so far.
    live : dict, optional
        The Foxglove live view's counters (``LiveView.status()``), when it runs.
    far_commands : int
        Position commands further than max_command_jump from the drive's
        reference so far (each approached at the drive's limits).

    """
    p, m = params, model
    o = m.output()
    rec_file, rec_bytes, rec_msgs, rec_err = recorder.status()
    eff = geometry.efficiency(p.mu_k * p.thread_factor, p.lead_angle)
    drive = m.drive_status()
    stepper = m.stepper_status()
    kind = 'stepper' if stepper is not None else 'drive'
    mode = drive['mode_name']
    if stepper is not None and mode == 'torque':
        mode = 'hold'                  # a stepper takes no torque: its state after reset
    level, msg = DiagnosticStatus.OK, f'running, {kind} enabled in {mode} mode'
    if stale:
        level, msg = DiagnosticStatus.WARN, (
            'torque command stale: applying 0 N m' if drive['mode_name'] == 'torque' else
            'command stale: quick stop, holding the position')
    gap = abs(m.reference_gap()) * p.lead_ratio
    if gap > 0.0:
        level, msg = DiagnosticStatus.WARN, (
            f'position command {gap:.6g} m beyond the reference: approaching it at the '
            "drive's limits (max_command_jump)")
    faults = p.active_faults()
    if faults:
        level, msg = DiagnosticStatus.WARN, f'injected faults active: {", ".join(faults)}'
    if rec_err:
        level, msg = DiagnosticStatus.WARN, f'recording: {rec_err}'
    if drive['fault']:
        level, msg = DiagnosticStatus.ERROR, (
            f'drive fault: {drive["fault_name"]}; '
            + ('stepper disabled, windings open' if stepper is not None else 'torque off')
            + ' until ~/clear_fault')
    if m.fault:
        level, msg = DiagnosticStatus.ERROR, f'simulation fault: {m.fault}'
    values = _values(p, m, o, drive, eff, clock_mode, sim_time_ns, target_rate, command_age,
                     stale, loop, lateness, counts, recorder)
    values += [('active_faults', ', '.join(faults) or 'none'),
               ('dropped_commands', str(dropped[0])), ('dropped_states', str(dropped[1])),
               ('far_position_commands', str(far_commands)),
               ('reference_gap_m', f'{gap:.6g}')]
    values += _ageing_values(m)
    if stepper is not None:
        values += stepper_values(stepper, p)
    if live is not None:
        values += live_view_values(live)
    status = DiagnosticStatus(level=level, name=f'{name}: lead screw axis', message=msg,
                              hardware_id=f'leadscrew_sim/{preset}',
                              values=[KeyValue(key=k, value=v) for k, v in values])
    arr = DiagnosticArray(status=[status])
    arr.header.stamp = stamp_msg(sim_time_ns)
    return arr


#: The diagnostics key of the stepper's lost full steps, and what it says about them.
LOST_STEPS_KEY = 'lost_full_steps_simulation_truth'
LOST_STEPS_NOTE = ('simulation truth, unknown to a real stepper driver: the full steps the '
                   'rotor lost against the commanded position (a multiple of 4); joint_states '
                   'reports the commanded position unless the motor has an encoder')


def stepper_values(stepper, p):
    """
    Return the (key, value) pairs of a stepper axis (``LeadScrewModel.stepper_status()``).

    Parameters
    ----------
    stepper : dict
        The stepper's status.
    p : ScrewParams
        The axis (its step angle and encoder).

    """
    return [
        ('drive_type', 'stepper'),
        ('stepper_state', 'enabled' if stepper['enabled'] else 'disabled (windings open)'),
        ('step_position_rad', f'{stepper["step_position"]:.9g}'),
        ('step_position_full_steps', f'{stepper["step_position"] / p.step_angle:.6f}'),
        ('step_rate_full_steps_per_s', f'{stepper["step_rate"] / p.step_angle:.6g}'),
        ('phase_current_a_A', f'{stepper["phase_current_a"]:.6g}'),
        ('phase_current_b_A', f'{stepper["phase_current_b"]:.6g}'),
        ('current_set_A', f'{stepper["current_set"]:.6g}'),
        ('joint_states_source', 'motor encoder' if p.encoder_counts > 0 else
         'commanded steps (no encoder)'),
        (LOST_STEPS_KEY, str(stepper['lost_full_steps'])),
        ('lost_full_steps_note', LOST_STEPS_NOTE),
    ]


#: The live view's counters in the diagnostics: key -> counter of ``LiveView.status()``.
LIVE_VIEW_KEYS = (
    ('foxglove_subscriptions', 'subscriptions'),
    ('foxglove_sent', 'sent'),
    ('foxglove_dropped', 'queue_dropped'),
    ('foxglove_outbox_full_reports', 'outbox_full_reports'),
    ('foxglove_bad_frames', 'bad_frames'),
    ('foxglove_unknown_channels', 'unknown_channels'),
    ('foxglove_oversized', 'oversized'),
    ('foxglove_refused', 'refused'),
    ('foxglove_malformed', 'malformed'),
    ('foxglove_client_messages', 'client_messages'),
    ('foxglove_inbox_dropped', 'inbox_dropped'),
)


def live_view_values(live):
    """
    Return the (key, value) pairs of the Foxglove live view's counters.

    ``foxglove_dropped``: messages the node's serving queue dropped (the
    loop never waits for a client). The SDK drops a slow client's oldest
    messages from its outbox without a count: ``foxglove_outbox_full_reports``
    counts its reports of that (at most one every 30 s).
    """
    return [(key, str(live.get(name, 0))) for key, name in LIVE_VIEW_KEYS]


def _ageing_values(m):
    """Return the (key, value) pairs of the axis's ageing (model.md, section 19)."""
    (w_lead, w_trail, backlash, preload, lub, mu_k, mu_s, temp, _heat,
     growth) = m.ageing_values()
    return [('wear_leading_m', f'{w_lead:.6g}'), ('wear_trailing_m', f'{w_trail:.6g}'),
            ('backlash_m', f'{backlash:.6g}'), ('preload_N', f'{preload:.6g}'),
            ('lubricant', f'{lub:.6g}'), ('mu_k', f'{mu_k:.6g}'), ('mu_s', f'{mu_s:.6g}'),
            ('screw_temperature_degC', f'{temp:.4f}'), ('thermal_growth_m', f'{growth:.6g}')]


def _values(p, m, o, drive, eff, clock_mode, sim_time_ns, target_rate, command_age, stale,
            loop, lateness, counts, recorder):
    """Return the (key, value) pairs of the status, values formatted as text."""
    rec_file, rec_bytes, rec_msgs, rec_err = recorder.status()
    commands, rejected, ignored = counts
    return [
        ('contact', o.contact_name), ('thread', 'stick' if o.stuck else 'slip'),
        ('self_locking', str(p.self_locking)), ('efficiency', f'{eff:.4f}'),
        ('nut_position_m', f'{o.nut_position:.6f}'),
        ('applied_torque_Nm', f'{o.motor_torque:.6g}'),
        ('axial_force_N', f'{o.axial_force:.6g}'),
        ('drive_mode', drive['mode_name']),
        ('drive_state', f'fault: {drive["fault_name"]}' if drive['fault'] else 'enabled'),
        ('following_error_rad', f'{drive["following_error"]:.6g}'),
        ('drive_torque_Nm', f'{drive["drive_torque"]:.6g}'),
        ('drive_rate_hz', f'{drive["effective_drive_rate"]:g}'),
        ('limit_switch_min', str(drive['limit_min'])),
        ('limit_switch_max', str(drive['limit_max'])), ('home_switch', str(drive['home'])),
        ('command_age_s', command_age), ('command_stale', str(stale)),
        ('clock_mode', clock_mode), ('sim_time_s', f'{sim_time_ns / NS:.6f}'),
        ('achieved_rate_hz', f'{loop.achieved_rate:.2f}'),
        ('target_rate_hz', f'{target_rate:g}'),
        ('lateness_p50_us', _us(lateness['p50'])), ('lateness_p99_us', _us(lateness['p99'])),
        ('lateness_max_us', _us(lateness['max'])),
        ('overruns', str(loop.overruns)), ('skipped_steps', str(loop.skipped_steps)),
        ('late_ticks', str(loop.late_ticks)), ('catchup_steps', str(loop.catchup_steps)),
        ('commands', str(commands)), ('rejected_commands', str(rejected)),
        ('ignored_commands', str(ignored)),
        ('substeps', str(m.nsub)),
        ('recording', str(recorder.active)), ('recording_file', rec_file),
        ('recording_bytes', str(rec_bytes)), ('recording_messages', str(rec_msgs)),
        ('recording_error', rec_err or ''),
        ('recording_dropped', str(recorder.dropped)),
    ]
