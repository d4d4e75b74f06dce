"""
Array layouts of the kernel: parameter vector, state, outputs and workspace.

Every index is a named constant; angles, rates and torques are in the "q sense"
of doc/model.md section 3 (q = hand * theta, so x = r_m tan(lambda) q for both
hands). Each constant's comment gives the meaning and unit of its slot.
The workspace offsets are derived from the sizes of the blocks they hold.

The friction law's constants fill one block of P, N_FRICTION slots from
P_FRICTION; friction.py alone assigns the slots inside it (pack_friction
writes them, friction_constants reads them), so the kernel never names them.
The drive's block follows it (so the friction block, which friction.py's
compiled code bakes in, has not moved since that module last changed).

The servo drive (drive.py, doc/model.md section 16) has its parameter slots
P_DRATE .. P_HYST, its state S_CMODE .. S_DWREF (the held command, then the
drive's own state: mode, target, integral, held torque, update phase, fault,
switches) and its outputs O_DMODE .. O_DWREF; a command row of step_held()
and run_series is N_CMD floats (mode, q, w, torque), all in the q sense.

The stepper (stepper.py, doc/model.md section 18) has its parameter slots
P_STEPPER .. P_SNOENC, its state S_IA .. S_SIDLE (phase currents, the step
generator) and its outputs O_IA .. O_ISET; it uses the servo drive's held
command, mode, target, quick stop and fault slots as they are.

The sensors (sensors.py) have their parameter slots P_ECPR .. P_SEED, the
faults the kernel applies P_EFRZ .. P_FINJ, their state S_EQ .. S_NREP (the
last readings and the noise counters) and the reported joint values O_JQ .. O_JV.
"""

# Parameter vector P (float64[NP]) ---------------------------------------------
P_RT = 0        # r_m tan(lambda): nut travel per screw radian [m/rad]
P_RC = 1        # r_m cos(lambda): sliding-velocity arm of the screw rate [m/rad]
P_SL = 2        # sin(lambda) [-]
P_CL = 3        # cos(lambda) [-]
P_B = 4         # axial backlash b, total free play [m]
P_K = 5         # thread contact stiffness [N/m]
P_C = 6         # thread contact damping [N s/m]
P_JM = 7        # motor rotor inertia [kg m^2]
P_JS = 8        # screw inertia [kg m^2]
P_KC = 9        # coupling stiffness [N m/rad]
P_CC = 10       # coupling damping [N m s/rad]
P_RIGID = 11    # 1.0: rigid coupling (motor and screw one body), 0.0: compliant
P_CS = 12       # screw bearing viscous damping [N m s/rad]
P_TS0 = 13      # screw bearing Coulomb torque [N m]
P_MUC = 14      # thrust collar friction coefficient [-]
P_RCOL = 15     # thrust collar mean friction radius [m]
P_MA = 16       # mass of nut A plus payload [kg]
P_MB = 17       # mass of the anti-backlash half-nut B [kg]
P_CX = 18       # nut guide viscous damping [N s/m]
P_FX0 = 19      # nut guide Coulomb force [N]
P_GS = 20       # g sin(inclination), gravity along +x [m/s^2]
P_KES = 21      # end stop stiffness [N/m]
P_CES = 22      # end stop damping [N s/m]
P_XMIN = 23     # lower end stop position of nut A [m]
P_XMAX = 24     # upper end stop position of nut A [m]
P_TMAX = 25     # motor torque saturation [N m]
P_TAU = 26      # motor torque lag time constant [s]; <= 0: no lag
P_AB = 27       # 1.0: split anti-backlash nut (body B active), 0.0: single nut
P_FP = 28       # anti-backlash preload force [N]
P_KP = 29       # anti-backlash spring stiffness [N/m]
P_FEXT = 30     # constant external axial force on nut A [N]
P_FRICTION = 31  # index of the first slot of the friction law's block
N_FRICTION = 10  # slots of the block: the Stribeck law uses 6, 4 are spare
# servo drive (drive.py; motor quantities in the q sense), after the friction block
P_DRATE = P_FRICTION + N_FRICTION   # drive_rate: drive update rate asked for [Hz]
P_DKP = P_DRATE + 1     # position gain K_p [1/s]
P_DKV = P_DRATE + 2     # velocity gain K_v [N m s/rad]
P_DTI = P_DRATE + 3     # velocity integral time T_i [s]; 0: no integral
P_DVMAX = P_DRATE + 4   # velocity limit of the motor [rad/s]
P_DQSD = P_DRATE + 5    # quick stop deceleration of the motor [rad/s^2]
P_DFEL = P_DRATE + 6    # following error limit [rad]; 0: off
P_DTLT = P_DRATE + 7    # torque limit time [s]; 0: off
P_DSCALE = P_DRATE + 8  # 1.0: position feedback from the linear scale, 0.0: motor encoder
P_DQ0 = P_DRATE + 9     # motor angle of the initial state [rad] (linear scale reference)
P_DX0 = P_DRATE + 10    # nut A position of the initial state [m] (linear scale reference)
P_LMIN = P_DRATE + 11   # min limit switch position [m]: trips at x <= P_LMIN
P_LMAX = P_DRATE + 12   # max limit switch position [m]: trips at x >= P_LMAX
P_HOME = P_DRATE + 13   # home switch position [m]: on at x >= P_HOME
P_HYST = P_DRATE + 14   # switch hysteresis [m]
# sensors (sensors.py, doc/model.md section 17) and the faults injected into the kernel
P_ECPR = P_DRATE + 15   # motor encoder counts per revolution; 0: no quantisation
P_ENOISE = P_DRATE + 16  # motor encoder noise standard deviation [rad]
P_EBIAS = P_DRATE + 17  # motor encoder bias [rad], q sense
P_EIDEAL = P_DRATE + 18  # 1.0: ideal encoder (no counts, noise or bias): it reads the truth
P_SFIT = P_DRATE + 19   # 1.0: a linear scale on nut A is fitted
P_SRES = P_DRATE + 20   # linear scale resolution [m]; 0: no quantisation
P_SNOISE = P_DRATE + 21  # linear scale noise standard deviation [m]
P_SBIAS = P_DRATE + 22  # linear scale bias [m]
P_SIDEAL = P_DRATE + 23  # 1.0: ideal scale (no resolution, noise or bias): it reads the truth
P_VFT = P_DRATE + 24    # velocity filter time constant [s]; 0: no filter
P_SEED = P_DRATE + 25   # sensor_seed, the key of the noise sequence [-]
P_EFRZ = P_DRATE + 26   # 1.0: encoder frozen (its reading holds, its velocity reads 0)
P_SFRZ = P_DRATE + 27   # 1.0: linear scale frozen
P_JAM = P_DRATE + 28    # 1.0: a rigid obstacle (end stop law) at P_JAMX blocks nut A
P_JAMX = P_DRATE + 29   # jam position [m]
P_TSCALE = P_DRATE + 30  # motor torque scale 0..1 (a weakened motor delivers this share)
P_FINJ = P_DRATE + 31   # 1.0: a drive fault is injected (latched while set)
# stepper motor and driver (stepper.py, doc/model.md section 18; motor quantities in the q sense)
P_STEPPER = P_DRATE + 32  # 1.0: the motor is a stepper with its driver (no servo drive)
P_NR = P_DRATE + 33     # rotor teeth N_r: electrical angle per motor angle [-]
P_USTEP = P_DRATE + 34  # microstep angle: step angle / microsteps [rad]
P_KM = P_DRATE + 35     # torque and back-EMF constant K_m [N m/A = V s/rad]
P_IRUN = P_DRATE + 36   # run current amplitude [A]
P_IHOLD = P_DRATE + 37  # hold current amplitude [A]
P_THOLD = P_DRATE + 38  # standstill time before the hold current [s]
P_RPH = P_DRATE + 39    # phase resistance R [ohm]
P_LPH = P_DRATE + 40    # phase inductance L [H]
P_TDET = P_DRATE + 41   # detent torque amplitude T_d [N m]
P_VSUP = P_DRATE + 42   # supply voltage V: the phase voltage clip [V]
P_KI = P_DRATE + 43     # current loop gain K_i [V/A]
P_SWMAX = P_DRATE + 44  # step generator's largest rate [rad/s]
P_SACC = P_DRATE + 45   # step generator's acceleration [rad/s^2]
P_BROT = P_DRATE + 46   # rotor viscous damping B [N m s/rad]
P_SNOENC = P_DRATE + 47  # 1.0: no encoder (joint_states reports the commanded steps)
P_OVS = P_DRATE + 48    # overspeed trip [rad/s]: a faster motor latches FAULT_OVERSPEED; 0: off
P_DJUMP = P_DRATE + 49  # max_command_jump as a motor angle [rad]; 0: off
P_DSLEW = P_DRATE + 50  # rate of the reference toward a command beyond P_DJUMP [rad/s]
# ageing (ageing.py, doc/model.md section 19): rates already multiplied by ageing_speedup
P_WEAR = P_DRATE + 51   # wear_rate times ageing_speedup [m/(N m)]; 0: no flank wear
P_ILIFE = P_DRATE + 52  # ageing_speedup / lubricant_life [1/m]; 0: the lubricant never runs out
P_MUSD = P_DRATE + 53   # apparent static coefficient of the dry thread mu_s_dry' [-]
P_MUKD = P_DRATE + 54   # apparent kinetic coefficient of the dry thread mu_k_dry' [-]
P_HCAP = P_DRATE + 55   # screw_heat_capacity / ageing_speedup [J/K]; 0: no heat
P_HLOSS = P_DRATE + 56  # screw_heat_loss to the ambient [W/K]
P_TAMB = P_DRATE + 57   # ambient_temperature [degC]
P_H2S = P_DRATE + 58    # heat_to_screw: share of the thread and bearing friction power [-]
P_ALPHA = P_DRATE + 59  # thermal_expansion of the screw [1/K]
P_XFIX = P_DRATE + 60   # fixed_bearing_x: where the screw does not move as it grows [m]
P_MUSW = P_DRATE + 61   # mu_s of the lubricated thread, as set (reported) [-]
P_MUKW = P_DRATE + 62   # mu_k of the lubricated thread, as set (reported) [-]
P_MUSDR = P_DRATE + 63  # mu_s_dry as set (reported) [-]
P_MUKDR = P_DRATE + 64  # mu_k_dry as set (reported) [-]
NP = P_DRATE + 65       # length of P

# State vector S (float64[N_STATE]) --------------------------------------------
S_QM = 0        # motor angle [rad]
S_WM = 1        # motor angle rate [rad/s]
S_Q = 2         # screw angle [rad]
S_DQ = 3        # screw angle rate [rad/s]
S_XA = 4        # nut A position [m]
S_VA = 5        # nut A velocity [m/s]
S_XB = 6        # half-nut B position [m]
S_VB = 7        # half-nut B velocity [m/s]
S_TE = 8        # applied (lagged, saturated) motor torque [N m]
S_T = 9         # simulated time [s]
S_WIN = 10      # motor work done since reset [J]
S_WEXT = 11     # work of the external force since reset [J]
S_EFRIC = 12    # energy dissipated by friction since reset [J]
S_EDAMP = 13    # energy dissipated by dampers since reset [J]
S_FAPREV = 14   # axial thread force of the last substep [N], for the collar limit
S_MODE0 = 15    # 4 slots: warm-start mode of thread A, thread B, bearing, guide (-1, 0, 1)
S_NSEARCH = 19  # count of LCP warm-start misses (diagnostic) [-]
# servo drive: the held command (as model.command or a command row gave it), q sense
S_CMODE = 20    # commanded mode (drive_modes.MODE_*)
S_CQ = 21       # commanded motor angle [rad] (position mode)
S_CW = 22       # commanded motor rate [rad/s] (velocity mode; feed-forward in position mode)
S_CT = 23       # commanded torque [N m] (torque mode; feed-forward otherwise)
# servo drive: its own state
S_DMODE = 24    # active mode (drive_modes.MODE_*; MODE_QUICKSTOP ends in MODE_POSITION)
S_DQREF = 25    # active position target [rad]
S_DINT = 26     # velocity integral I, the integral of the velocity error [rad]
S_DTOUT = 27    # drive torque command held between updates (before lag) [N m]
S_DPHASE = 28   # substeps since the last drive update (0 .. m-1) [-]
S_DFAULT = 29   # latched fault code (drive_modes.FAULT_*); torque off while nonzero
S_DTLIM = 30    # time the velocity loop output has been at +-max_torque [s]
S_DQS = 31      # 1.0: the held command is a quick stop that has started (or ended in a hold)
S_DWQS = 32     # quick stop velocity ramp [rad/s]; NaN: start from the measured rate
S_SWMIN = 33    # min limit switch tripped (1.0) or not (0.0)
S_SWMAX = 34    # max limit switch tripped (1.0) or not (0.0)
S_HOME = 35     # home switch on (1.0) or off (0.0)
S_DFERR = 36    # following error q_ref - q_fb of the last position-mode update [rad]
S_DWREF = 37    # velocity reference of the last drive update [rad/s]
# sensors: the readings of the last sample (the end of a drive period), q sense
S_EQ = 38       # motor encoder reading [rad]
S_EW = 39       # motor rate from the encoder (difference quotient, filtered) [rad/s]
S_XS = 40       # linear scale reading [m]
S_VS = 41       # nut velocity from the scale (difference quotient, filtered) [m/s]
S_NSAMP = 42    # sensor samples taken since reset: the index of the next noise pair [-]
S_JAM = 43      # side the jam blocks: 1 motion toward +x, -1 toward -x, 0 no jam [-]
S_NREP = 44     # readings reported between drive samples since reset: their noise index [-]
# stepper (stepper.py): phase currents and the step generator, q sense
S_IA = 45       # phase A current [A]
S_IB = 46       # phase B current [A] (q sense: h times the physical phase B current)
S_SPOS = 47     # step generator position: the motor angle commanded, unquantised [rad]
S_SRATE = 48    # step generator rate [rad/s]
S_SK = 49       # microstep index k of the commanded angle P_DQ0 + k microstep [-]
S_SIDLE = 50    # standstill time since the last microstep [s]
# ageing (ageing.py): flank wear, lubricant and screw temperature; kept by a reset
S_WLA = 51      # wear depth of nut A's leading (lower) flank [m]
S_WUA = 52      # wear depth of nut A's trailing (upper) flank [m]
S_WLB = 53      # wear depth of half-nut B's leading flank [m]
S_WUB = 54      # wear depth of half-nut B's trailing flank [m]
S_LUB = 55      # lubricant state L: 1 fresh .. 0 used up [-]
S_TEMP = 56     # screw temperature [degC]
N_AGEING = 6    # slots of the ageing state, from S_WLA
N_STATE = 57    # length of S

# Per-step outputs out (float64[NO]), values of the last substep -----------------
O_NLA = 0       # lower flank normal force of nut A [N]
O_NUA = 1       # upper flank normal force of nut A [N]
O_NLB = 2       # lower flank normal force of half-nut B [N]
O_NUB = 3       # upper flank normal force of half-nut B [N]
O_FFA = 4       # thread friction force of nut A along the flank [N]
O_FFB = 5       # thread friction force of half-nut B along the flank [N]
O_VSA = 6       # thread sliding velocity of nut A [m/s]
O_VSB = 7       # thread sliding velocity of half-nut B [m/s]
O_STICKA = 8    # thread A: 1 stuck, 0 sliding, -1 no load
O_STICKB = 9    # thread B: 1 stuck, 0 sliding, -1 no load
O_CONTA = 10    # thread A contact: 1 leading (lower) flank, -1 trailing, 0 backlash
O_CONTB = 11    # thread B contact: 1 leading (lower) flank, -1 trailing, 0 backlash
O_FAX = 12      # axial thread force on the nut(s) [N]
O_TTH = 13      # thread torque on the screw [N m]
O_TE = 14       # applied motor torque [N m]
O_TBR = 15      # bearing + collar friction torque [N m]
O_FG = 16       # nut guide Coulomb force [N]
O_NSUB = 17     # substeps taken in the step [-]
O_DMODE = 18    # drive mode at the end of the step (drive_modes.MODE_*)
O_DFAULT = 19   # drive fault code (drive_modes.FAULT_*)
O_SWMIN = 20    # min limit switch: 1 tripped, 0 not
O_SWMAX = 21    # max limit switch: 1 tripped, 0 not
O_HOME = 22     # home switch: 1 on, 0 off
O_DFERR = 23    # following error q_ref - q_fb [rad] (position mode, else 0)
O_DTCMD = 24    # drive torque command, before lag and saturation of the motor [N m]
O_DWREF = 25    # velocity reference of the last drive update [rad/s] (0 in torque mode)
# what the sensors report at the end of the step (joint_states), q sense
O_JQ = 26       # screw joint angle: the encoder reading (the true screw angle if ideal) [rad]
O_JW = 27       # screw joint rate from the encoder [rad/s]
O_JX = 28       # nut joint position: the scale, or the encoder through the lead [m]
O_JV = 29       # nut joint velocity, from the same sensor [m/s]
O_JAM = 30      # side the jam blocks (S_JAM) at the end of the step [-]
# stepper (stepper.py), q sense; 0 for the servo drive
O_IA = 31       # phase A current [A]
O_IB = 32       # phase B current [A] (q sense)
O_SCMD = 33     # commanded motor angle: P_DQ0 + S_SK microsteps [rad]
O_SRATE = 34    # step generator rate [rad/s]
O_ISET = 35     # phase current amplitude set: run or hold current, 0 disabled [A]
# ageing (ageing.py) at the end of the step
O_WLA = 36      # wear of nut A's leading (lower) flank [m] (S_WLA)
O_WUA = 37      # wear of nut A's trailing (upper) flank [m]
O_WLB = 38      # wear of half-nut B's leading flank [m]
O_WUB = 39      # wear of half-nut B's trailing flank [m]
O_BLASH = 40    # effective backlash: the set one opened by the wear [m]
O_PRELOAD = 41  # anti-backlash preload the worn flanks leave [N] (0: single nut)
O_LUB = 42      # lubricant state L [-]
O_MUK = 43      # kinetic thread friction coefficient mu_k at L [-]
O_MUS = 44      # static thread friction coefficient mu_s at L [-]
O_TEMP = 45     # screw temperature [degC]
O_HEAT = 46     # heat flow into the screw from the step's friction [W]
O_GROW = 47     # thermal growth of the screw at nut A [m]
NO = 48         # length of out

# Records of run_series: one row per step ------------------------------------------
REC_STATE = 14                  # a row starts with S[0:REC_STATE] (positions .. energies)
REC_ROW = REC_STATE + NO        # then the NO outputs: floats per row

# Friction elements --------------------------------------------------------------
MAXE = 4        # friction elements: thread A, thread B, bearing/collar, guide

# Float workspace wk (float64[WK_FLOAT]): offsets of consecutive blocks ---------------
WK_W = 0                        # LCP Delassus matrix, MAXE x MAXE [1/kg, 1/(kg m^2)]
WK_V0 = WK_W + MAXE * MAXE      # LCP free velocities of the active elements, MAXE
WK_LIM = WK_V0 + MAXE           # LCP impulse limits, MAXE [N s, N m s]
WK_P = WK_LIM + MAXE            # LCP impulses (solution), MAXE [N s, N m s]
WK_A = WK_P + MAXE              # LCP elimination matrix, MAXE x MAXE
WK_R = WK_A + MAXE * MAXE       # LCP elimination right-hand side, MAXE
WK_LCP = WK_R + MAXE            # floats of LCP scratch: 2 MAXE^2 + 4 MAXE
WK_IO = WK_LCP                  # step()'s inputs: commanded torque [N m], force [N]
WK_NIO = 2                      # floats of step()'s inputs
WK_CMD = WK_IO + WK_NIO         # step_held()'s command row: mode, q, w, torque (N_CMD floats)
N_CMD = 4                       # floats of a command row (mode, q [rad], w [rad/s], t [N m])
WK_REC = WK_CMD + N_CMD         # step()'s scratch record row, REC_ROW floats
WK_FLOAT = WK_REC + REC_ROW     # length of wk

# Integer workspace iwk (int64[WK_INT]) ----------------------------------------------
IWK_MODE = 0                    # LCP modes of the active elements, MAXE
IWK_EID = IWK_MODE + MAXE       # element id (0 .. MAXE-1) of each active slot, MAXE
IWK_IDX = IWK_EID + MAXE        # LCP free-element index list, MAXE
IWK_TRIAL = IWK_IDX + MAXE      # LCP trial modes of the exhaustive search, MAXE
WK_INT = IWK_TRIAL + MAXE       # length of iwk
