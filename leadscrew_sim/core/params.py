"""
Validated, immutable physical parameters of the lead screw axis (SI units).

Every field carries its unit, a description and its allowed range in the
dataclass metadata (:mod:`leadscrew_sim.core.fields`); the ROS node builds its
parameter descriptors from them. Presets: :mod:`leadscrew_sim.core.presets`.
"""
import dataclasses
import math

from . import geometry
from .fields import document, field, ParameterError, Schema

__all__ = ['ParameterError', 'ScrewParams']

#: Values of drive_feedback: where the drive's position loop takes its angle from.
DRIVE_FEEDBACKS = ('motor_encoder', 'linear_scale')

#: Values of drive_type: the servo drive (doc/model.md section 16) or the stepper (section 14).
DRIVE_TYPES = ('servo', 'stepper')


@document
@dataclasses.dataclass(frozen=True)
class ScrewParams(Schema):
    """Physical parameters of screw, nut, load, motor and integration (SI)."""

    # Geometry (doc/model.md section 2)
    thread_form: str = field('trapezoidal', '-', 'thread form; sets the axial half-angle psi_a '
                             '(square 0, acme/stub_acme 14.5 deg, trapezoidal 15 deg)',
                             choices=tuple(geometry.THREAD_HALF_ANGLES), read_only=True)
    hand: str = field('right', '-', 'thread hand; right: positive screw rotation moves the nut '
                      'toward -x', choices=('right', 'left'), read_only=True)
    major_diameter: float = field(0.012, 'm', 'nominal (major) diameter D', 1e-4, 1.0,
                                  read_only=True)
    pitch: float = field(0.003, 'm', 'thread pitch p', 1e-5, 0.1, read_only=True)
    starts: int = field(1, '-', 'number of thread starts n_s', 1, 20, read_only=True)
    pitch_diameter: float = field(0.0, 'm', 'pitch (mean) diameter d_m; 0 means D - p/2',
                                  0.0, 1.0, read_only=True)
    # Friction (section 6)
    mu_s: float = field(0.2, '-', 'static thread friction coefficient', 0.0, 2.0)
    mu_k: float = field(0.15, '-', 'kinetic (Coulomb) thread friction coefficient', 0.0, 2.0)
    stribeck_velocity: float = field(1e-3, 'm/s', 'Stribeck velocity v_st of the '
                                     'static-to-kinetic drop', 1e-7, 10.0, lo_open=True)
    stribeck_exponent: float = field(1.0, '-', 'Stribeck shape exponent delta_st', 0.1, 10.0)
    mu_viscous: float = field(0.0, 's/m', 'viscous friction slope mu_v (negative: velocity '
                              'weakening)', -100.0, 100.0)
    collar_mu: float = field(0.0, '-', 'thrust collar friction coefficient mu_c', 0.0, 2.0)
    collar_radius: float = field(0.0, 'm', 'thrust collar mean friction radius r_c', 0.0, 1.0)
    # Thread contact (section 5)
    backlash: float = field(1e-4, 'm', 'axial backlash b (total free play)', 0.0, 0.1)
    contact_stiffness: float = field(1e8, 'N/m', 'axial thread contact stiffness k', 1e3, 1e11)
    contact_damping: float = field(2e3, 'N s/m', 'axial thread contact damping c', 0.0, 1e7)
    # Bodies (section 4)
    motor_inertia: float = field(1e-5, 'kg m^2', 'motor rotor inertia J_m', 1e-9, 10.0)
    screw_inertia: float = field(2e-6, 'kg m^2', 'screw inertia J_s', 1e-9, 10.0)
    coupling_stiffness: float = field(0.0, 'N m/rad', 'coupling torsional stiffness k_c; '
                                      '0 means rigid', 0.0, 1e8)
    coupling_damping: float = field(0.0, 'N m s/rad', 'coupling damping c_c', 0.0, 1e5)
    bearing_viscous: float = field(1e-5, 'N m s/rad', 'screw bearing viscous damping c_s',
                                   0.0, 1e3)
    bearing_coulomb: float = field(0.0, 'N m', 'screw bearing Coulomb torque T_s0', 0.0, 1e3)
    nut_mass: float = field(0.05, 'kg', 'nut mass m_n', 1e-6, 1e4)
    payload_mass: float = field(1.0, 'kg', 'payload mass m_p carried by the nut', 0.0, 1e5)
    guide_viscous: float = field(1.0, 'N s/m', 'nut guide viscous damping c_x', 0.0, 1e6)
    guide_coulomb: float = field(0.0, 'N', 'nut guide Coulomb force F_x0', 0.0, 1e6)
    inclination: float = field(math.pi / 2, 'rad', 'axis inclination beta; pi/2 is vertical '
                               'with +x up', -math.pi / 2, math.pi / 2)
    gravity: float = field(9.80665, 'm/s^2', 'gravitational acceleration g', 0.0, 100.0)
    external_force: float = field(0.0, 'N', 'constant external axial force on the nut, +x',
                                  -1e7, 1e7)
    stroke_min: float = field(-0.1, 'm', 'lower end stop position x_min', -100.0, 100.0)
    stroke_max: float = field(0.1, 'm', 'upper end stop position x_max', -100.0, 100.0)
    end_stop_stiffness: float = field(1e7, 'N/m', 'end stop stiffness', 0.0, 1e11)
    end_stop_damping: float = field(1e3, 'N s/m', 'end stop damping (never pulls)', 0.0, 1e7)
    # Motor
    max_torque: float = field(2.0, 'N m', 'motor torque saturation T_max', 1e-6, 1e5)
    torque_lag: float = field(0.0, 's', 'motor torque first-order lag tau_e; 0 means none',
                              0.0, 10.0)
    # Servo drive (doc/model.md section 16; angles and rates of the motor)
    drive_rate: float = field(4000.0, 'Hz', 'servo drive update rate asked for; the drive '
                              'updates every m = max(1, round(substeps per step * update_rate '
                              '/ drive_rate)) substeps', 1.0, 1e6)
    position_gain: float = field(62.8, '1/s', 'position loop gain K_p', 0.0, 1e5)
    velocity_gain: float = field(3.85e-3, 'N m s/rad', 'velocity loop gain K_v', 0.0, 1e6)
    velocity_integral_time: float = field(0.0127, 's', 'velocity loop integral time T_i; 0 '
                                          'means no integral', 0.0, 100.0)
    velocity_limit: float = field(300.0, 'rad/s', 'motor velocity limit of the velocity '
                                  'reference', 0.0, 1e5, lo_open=True)
    quick_stop_deceleration: float = field(1000.0, 'rad/s^2', 'motor deceleration of a quick '
                                           'stop', 0.0, 1e8, lo_open=True)
    following_error_limit: float = field(0.0, 'rad', 'motor angle following error that latches '
                                         'a drive fault in position mode; 0 means off',
                                         0.0, 1e6)
    torque_limit_time: float = field(0.0, 's', 'time the velocity loop output may stay at '
                                     '+-max_torque before a drive fault latches; 0 means off',
                                     0.0, 3600.0)
    max_screw_velocity: float = field(0.0, 'rad/s', 'rated speed of the axis, the URDF joint '
                                      'velocity limit: the velocity reference stays within it, '
                                      'and in every drive mode an overspeed fault latches when '
                                      'the motor turns faster than 1.2 times it (every preset '
                                      'sets it); 0 means none', 0.0, 1e5)
    max_command_jump: float = field(0.0, 'm', 'largest nut position command step the drive '
                                    'takes at once: a position command further than this from '
                                    'the reference (or, entering position mode, from the nut) '
                                    'is approached at the drive velocity limit, capped by '
                                    'max_screw_velocity; 0 means off', 0.0, 100.0)
    drive_feedback: str = field('motor_encoder', '-', 'position loop feedback: the motor '
                                'encoder, or the linear scale (nut position mapped to a motor '
                                'angle through the lead)', choices=DRIVE_FEEDBACKS)
    limit_min_position: float = field(-1000.0, 'm', 'min limit switch: trips at x <= this, '
                                      'releases above it plus the hysteresis; the default '
                                      'lies beyond any stroke (no switch)', -1000.0, 1000.0)
    limit_max_position: float = field(1000.0, 'm', 'max limit switch: trips at x >= this, '
                                      'releases below it less the hysteresis; the default '
                                      'lies beyond any stroke (no switch)', -1000.0, 1000.0)
    home_position: float = field(1000.0, 'm', 'home switch: on at x >= this, off below it '
                                 'less the hysteresis (an output only)', -1000.0, 1000.0)
    switch_hysteresis: float = field(1e-3, 'm', 'hysteresis of the limit and home switches',
                                     0.0, 1.0)
    # Stepper motor and driver (doc/model.md section 18; used with drive_type stepper)
    drive_type: str = field('servo', '-', 'the motor and its drive: a servo motor with the '
                            'servo drive, or a two-phase hybrid stepper with a microstepping '
                            'driver and a step generator (position and velocity commands only)',
                            choices=DRIVE_TYPES, read_only=True)
    step_angle: float = field(math.pi / 100, 'rad', 'full step angle pi / (2 N_r) of the '
                              'stepper (1.8 deg: N_r = 50 rotor teeth)', 0.0, math.pi / 2,
                              lo_open=True, read_only=True)
    microsteps: int = field(16, '-', 'microsteps per full step of the driver, a power of two '
                            '1 .. 256', 1, 256, read_only=True)
    holding_torque: float = field(0.4, 'N m', 'holding torque T_h = K_m I at the phase '
                                  'current amplitude I = run_current (peak static torque)',
                                  0.0, 1e3, lo_open=True)
    run_current: float = field(1.7, 'A', 'phase current amplitude while stepping (the peak of '
                               'the sine and cosine microstep currents)', 0.0, 100.0,
                               lo_open=True)
    hold_current: float = field(0.85, 'A', 'phase current amplitude after hold_current_delay '
                                'at standstill; at most run_current', 0.0, 100.0)
    hold_current_delay: float = field(0.5, 's', 'standstill time after the last microstep '
                                      'before the current drops to hold_current', 0.0, 3600.0)
    phase_resistance: float = field(1.5, 'ohm', 'winding resistance R of a phase', 0.0, 1e3,
                                    lo_open=True)
    phase_inductance: float = field(2.8e-3, 'H', 'winding inductance L of a phase', 0.0, 10.0,
                                    lo_open=True)
    detent_torque: float = field(0.022, 'N m', 'detent torque amplitude T_d of the unpowered '
                                 'motor (-T_d sin(4 theta_e)); below holding_torque', 0.0, 1e3)
    supply_voltage: float = field(24.0, 'V', 'driver supply voltage V: each phase voltage is '
                                  'clipped to +-V; above run_current * phase_resistance',
                                  0.0, 1e3, lo_open=True)
    current_loop_bandwidth: float = field(5000.0, 'Hz', 'bandwidth f_c of the driver\'s '
                                          'averaged current loop: v = clip(R i* + K_i (i* - '
                                          'i), +-V), K_i = 2 pi f_c L - R', 1.0, 1e6)
    max_step_rate: float = field(2000.0, 'full steps/s', 'largest step rate of the step '
                                 'generator (velocity of the trapezoid)', 0.0, 1e6, lo_open=True)
    step_acceleration: float = field(20000.0, 'full steps/s^2', 'acceleration and deceleration '
                                     'of the step generator\'s ramps (trapezoid, velocity '
                                     'changes, quick stop)', 0.0, 1e9, lo_open=True)
    rotor_damping: float = field(1e-4, 'N m s/rad', 'viscous damping B of the stepper rotor',
                                 0.0, 10.0)
    # Sensors (doc/model.md section 17); all ideal by default
    encoder_counts: int = field(0, '-', 'motor encoder counts per revolution N; 0 means no '
                                'quantisation', 0, 2 ** 31 - 1)
    encoder_noise: float = field(0.0, 'rad', 'standard deviation of the motor encoder\'s '
                                 'Gaussian noise (added before the quantisation)', 0.0, 1.0)
    encoder_bias: float = field(0.0, 'rad', 'motor encoder bias, added to the true angle',
                                -10.0, 10.0)
    linear_scale: bool = field(True, '-', 'a linear scale on the nut is fitted: joint_states '
                               'reports the nut from it; false: from the motor encoder through '
                               'the lead (backlash then invisible)', read_only=True)
    scale_resolution: float = field(0.0, 'm', 'linear scale resolution r; 0 means no '
                                    'quantisation', 0.0, 0.01)
    scale_noise: float = field(0.0, 'm', 'standard deviation of the linear scale\'s Gaussian '
                               'noise (added before the quantisation)', 0.0, 0.01)
    scale_bias: float = field(0.0, 'm', 'linear scale bias, added to the true position',
                              -1.0, 1.0)
    velocity_filter_time: float = field(0.0, 's', 'time constant of the first-order filter of '
                                        'the velocities from the sensors (difference '
                                        'quotients over the drive period); 0 means none',
                                        0.0, 10.0)
    sensor_seed: int = field(0, '-', 'seed of the sensor noise and of the dropped messages',
                             0, 2 ** 31 - 1)
    state_delay: int = field(0, 'tick', 'joint_states and nut_position are delivered this many '
                             'ticks after their sampling (stamped with the sampling time)',
                             0, 10000)
    command_delay: int = field(0, 'tick', 'a command acts this many ticks after it arrives',
                               0, 10000)
    # Faults injected at run time (ROS names fault.<name>)
    fault_encoder_freeze: bool = field(False, '-', 'the motor encoder freezes: its reading '
                                       'holds and its velocity reads 0')
    fault_scale_freeze: bool = field(False, '-', 'the linear scale freezes likewise')
    fault_state_drop_rate: float = field(0.0, '-', 'share of the joint_states and nut_position '
                                         'messages dropped (seeded)', 0.0, 1.0)
    fault_command_drop_rate: float = field(0.0, '-', 'share of the received commands dropped '
                                           '(seeded; external_force is never dropped)',
                                           0.0, 1.0)
    fault_jam: bool = field(False, '-', 'a rigid obstacle at fault.jam_position blocks the '
                            'nut on the side it lies (end stop stiffness and damping)')
    fault_jam_position: float = field(0.0, 'm', 'position of the jam', -100.0, 100.0)
    fault_motor_torque_scale: float = field(1.0, '-', 'share of the commanded torque the '
                                            '(weakened) motor delivers', 0.0, 1.0)
    fault_drive_fault: bool = field(False, '-', 'latch a drive fault now (torque off); it '
                                    'stays latched while true and ~/clear_fault clears it '
                                    'once false')
    # Ageing (section 19): wear, lubricant, heat; every rate 0 (off) by default
    wear_rate: float = field(0.0, 'm/(N m)', 'Archard flank wear: depth per normal force and '
                             'sliding distance', 0.0, 1e-3)
    lubricant_life: float = field(0.0, 'm', 'thread sliding distance over which the lubricant '
                                  'falls to 1/e; 0 means it never runs out', 0.0, 1e12)
    mu_s_dry: float = field(0.3, '-', 'static thread friction coefficient once the lubricant '
                            'is used up', 0.0, 2.0)
    mu_k_dry: float = field(0.25, '-', 'kinetic thread friction coefficient once the '
                            'lubricant is used up', 0.0, 2.0)
    screw_heat_capacity: float = field(0.0, 'J/K', 'heat capacity C of the screw; 0 means no '
                                       'heating', 0.0, 1e8)
    screw_heat_loss: float = field(0.5, 'W/K', 'heat loss G of the screw to the ambient',
                                   0.0, 1e6)
    ambient_temperature: float = field(20.0, 'degC', 'ambient temperature, where the screw '
                                       'has its nominal length', -100.0, 500.0)
    heat_to_screw: float = field(0.5, '-', 'share of the thread and bearing friction power '
                                 'that heats the screw', 0.0, 1.0)
    thermal_expansion: float = field(11.5e-6, '1/K', 'thermal expansion coefficient alpha '
                                     'of the screw (steel 11.5e-6)', 0.0, 1e-3)
    fixed_bearing_x: float = field(0.0, 'm', 'nut position of the fixed bearing, from which '
                                   'the screw grows', -100.0, 100.0)
    ageing_speedup: float = field(1.0, '-', 'multiplies the wear and lubricant rates and '
                                  'divides the heat capacity (time-lapse ageing)', 0.0, 1e12,
                                  lo_open=True)
    # Anti-backlash split nut (section 7)
    anti_backlash: bool = field(False, '-', 'split anti-backlash nut with preload spring',
                                read_only=True)
    preload_force: float = field(0.0, 'N', 'anti-backlash preload F_p', 0.0, 1e6)
    preload_stiffness: float = field(1e5, 'N/m', 'anti-backlash spring stiffness k_p',
                                     1.0, 1e10)
    second_nut_mass: float = field(0.01, 'kg', 'mass of the second half-nut m_b', 1e-6, 1e4)
    # Initial state and integration (section 8)
    initial_position: float = field(0.0, 'm', 'initial nut position x_0', -100.0, 100.0,
                                    read_only=True)
    substep: float = field(0.0, 's', 'integration substep upper bound; 0 means automatic '
                           '(0.2 / omega_max of the stiffest mode)', 0.0, 1e-2)

    def advisories(self):
        """Return warnings about a valid but unusual set (a list of one-line strings)."""
        notes = []
        if self.mu_k > self.mu_s:
            notes.append(f"mu_k {self.mu_k!r} exceeds mu_s {self.mu_s!r}: the thread friction "
                         'rises from standstill to sliding (a negative Stribeck drop); the '
                         'static coefficient is usually the larger')
        return notes

    def active_faults(self):
        """Return the injected faults that are on, as ``fault.<name>[=value]`` strings."""
        on = []
        for flag in ('encoder_freeze', 'scale_freeze', 'drive_fault'):
            if getattr(self, f'fault_{flag}'):
                on.append(f'fault.{flag}')
        for rate in ('state_drop_rate', 'command_drop_rate'):
            if getattr(self, f'fault_{rate}') > 0.0:
                on.append(f'fault.{rate}={getattr(self, f"fault_{rate}"):g}')
        if self.fault_jam:
            on.append(f'fault.jam at {self.fault_jam_position:g} m')
        if self.fault_motor_torque_scale < 1.0:
            on.append(f'fault.motor_torque_scale={self.fault_motor_torque_scale:g}')
        return on

    # Derived geometry -------------------------------------------------------
    @property
    def lead(self):
        """Lead l [m]."""
        return geometry.lead(self.pitch, self.starts)

    @property
    def reference_speed_limit(self):
        """Return the velocity reference limit [rad/s]: velocity_limit within the rated speed."""
        if self.max_screw_velocity > 0.0:
            return min(self.velocity_limit, self.max_screw_velocity)
        return self.velocity_limit

    @property
    def lead_ratio(self):
        """Nut travel per screw angle l / (2 pi) [m/rad]."""
        return self.lead / (2.0 * math.pi)

    @property
    def mean_diameter(self):
        """Effective pitch diameter d_m [m]."""
        return self.pitch_diameter or geometry.pitch_diameter(self.major_diameter, self.pitch)

    @property
    def r_m(self):
        """Pitch radius r_m [m]."""
        return self.mean_diameter / 2.0

    @property
    def lead_angle(self):
        """Lead angle lambda [rad]."""
        return geometry.lead_angle(self.lead, self.mean_diameter)

    @property
    def half_angle(self):
        """Axial thread half-angle psi_a [rad]."""
        return geometry.THREAD_HALF_ANGLES[self.thread_form]

    @property
    def thread_factor(self):
        """1 / cos(psi_n): multiplies mu to give mu'."""
        return 1.0 / math.cos(geometry.normal_half_angle(self.half_angle, self.lead_angle))

    @property
    def hand_sign(self):
        """Return h of q = h theta: -1 for a right-hand thread, +1 for left."""
        return -1.0 if self.hand == 'right' else 1.0

    @property
    def moving_mass(self):
        """All axially moving mass [kg]."""
        return self.nut_mass + self.payload_mass + (
            self.second_nut_mass if self.anti_backlash else 0.0)

    @property
    def self_locking(self):
        """Return True if the thread holds any axial load with zero torque."""
        return geometry.is_self_locking(self.mu_s * self.thread_factor, self.lead_angle)

    def _check_consistency(self):
        if self.pitch_diameter == 0.0 and self.major_diameter - self.pitch / 2.0 <= 0.0:
            raise ParameterError('pitch', f'{self.pitch} m gives a pitch diameter '
                                 f'D - p/2 <= 0 with major_diameter {self.major_diameter} m')
        if self.pitch_diameter > self.major_diameter:
            raise ParameterError('pitch_diameter', f'{self.pitch_diameter} m exceeds '
                                 f'major_diameter {self.major_diameter} m')
        if self.backlash >= self.pitch:
            raise ParameterError('backlash', f'{self.backlash} m must be smaller than the '
                                 f'pitch {self.pitch} m')
        if self.stroke_min >= self.stroke_max:
            raise ParameterError('stroke_min', f'{self.stroke_min} m must be below '
                                 f'stroke_max {self.stroke_max} m')
        if not self.stroke_min <= self.initial_position <= self.stroke_max:
            raise ParameterError('initial_position', f'{self.initial_position} m lies '
                                 f'outside the stroke [{self.stroke_min}, {self.stroke_max}] m')
        jam = max(self.mu_s, self.mu_k) * self.thread_factor * math.tan(self.lead_angle)
        if jam >= 1.0:
            raise ParameterError('mu_s', f"mu' tan(lambda) = {jam:.3g}"
                                 ' >= 1: the thread jams and cannot be driven against a load'
                                 ' (reduce friction or the lead angle)')
        dry = max(self.mu_s_dry, self.mu_k_dry) * self.thread_factor * math.tan(self.lead_angle)
        if self.lubricant_life > 0.0 and dry >= 1.0:
            raise ParameterError('mu_s_dry', f"mu' tan(lambda) = {dry:.3g} >= 1 once the "
                                 'lubricant is used up: the dry thread jams (reduce the dry '
                                 'friction or the lead angle)')
        if self.limit_min_position >= self.limit_max_position:
            raise ParameterError('limit_min_position', f'{self.limit_min_position} m must be '
                                 f'below limit_max_position {self.limit_max_position} m')
        if self.drive_feedback == 'linear_scale' and not self.linear_scale:
            raise ParameterError('drive_feedback', "'linear_scale' needs a fitted scale "
                                 '(linear_scale true)')
        if self.drive_type == 'stepper':
            self._check_stepper()
        if self.collar_mu > 0.0 and self.collar_radius == 0.0:
            raise ParameterError('collar_radius', '0 m while collar_mu > 0: give the collar '
                                 'friction radius')

    def _check_stepper(self):
        """Check the stepper's figures against each other (drive_type stepper)."""
        m = self.microsteps
        if m & (m - 1):
            raise ParameterError('microsteps', f'{m} is not a power of two (allowed: 1, 2, 4, '
                                 '8, 16, 32, 64, 128, 256)')
        if self.hold_current > self.run_current:
            raise ParameterError('hold_current', f'{self.hold_current!r} A exceeds run_current '
                                 f'{self.run_current!r} A (allowed: [0, {self.run_current!r}] A)')
        if self.detent_torque >= self.holding_torque:
            raise ParameterError('detent_torque', f'{self.detent_torque!r} N m is not below '
                                 f'holding_torque {self.holding_torque!r} N m (allowed: '
                                 f'[0, {self.holding_torque!r}) N m)')
        need = self.run_current * self.phase_resistance
        if self.supply_voltage <= need:
            raise ParameterError('supply_voltage', f'{self.supply_voltage!r} V cannot drive '
                                 f'run_current {self.run_current!r} A through phase_resistance '
                                 f'{self.phase_resistance!r} ohm (allowed: above {need:.6g} V, '
                                 'up to 1000 V)')
        f_min = self.phase_resistance / (2.0 * math.pi * self.phase_inductance)
        if self.current_loop_bandwidth < f_min:
            raise ParameterError('current_loop_bandwidth', f'{self.current_loop_bandwidth!r} '
                                 f'Hz is below the winding\'s own R / (2 pi L) = {f_min:.6g} Hz '
                                 f'(allowed: [{f_min:.6g}, 1e6] Hz)')
        if self.drive_feedback == 'linear_scale':
            raise ParameterError('drive_feedback', "'linear_scale': the stepper drive runs open "
                                 "loop (allowed: 'motor_encoder')")

    @property
    def rotor_teeth(self):
        """Rotor teeth N_r = pi / (2 step_angle) of the stepper: electrical per motor angle."""
        return math.pi / (2.0 * self.step_angle)

    @property
    def torque_constant(self):
        """Stepper torque constant K_m = holding_torque / run_current [N m/A = V s/rad]."""
        return self.holding_torque / self.run_current
