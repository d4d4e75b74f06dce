"""
Array layouts of the kernel: parameter vector, state, outputs and workspace.

Every index is a named constant; angles, rates and torques are in the "q sense"
of physics.md section 3 (q = hand * theta, so x = r_m tan(lambda) q for both
hands). Each constant's comment gives the meaning and unit of its slot.
The workspace offsets are derived from the sizes of the blocks they hold.

The friction law's constants fill one block of P, N_FRICTION slots from
P_FRICTION, the last block so that it can grow without moving other slots;
friction.py alone assigns the slots inside it (pack_friction writes them,
friction_constants reads them), so the kernel never names them.
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
NP = P_FRICTION + N_FRICTION    # length of P

# State vector S (float64[NS]) -------------------------------------------------
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
NS = 20         # length of S

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
NO = 18         # length of out

# Records of run_series: one row per step ------------------------------------------
REC_STATE = 10                  # a row starts with S[0:REC_STATE] (positions .. time)
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
WK_REC = WK_IO + WK_NIO         # step()'s scratch record row, REC_ROW floats
WK_FLOAT = WK_REC + REC_ROW     # length of wk

# Integer workspace iwk (int64[WK_INT]) ----------------------------------------------
IWK_MODE = 0                    # LCP modes of the active elements, MAXE
IWK_EID = IWK_MODE + MAXE       # element id (0 .. MAXE-1) of each active slot, MAXE
IWK_IDX = IWK_EID + MAXE        # LCP free-element index list, MAXE
IWK_TRIAL = IWK_IDX + MAXE      # LCP trial modes of the exhaustive search, MAXE
WK_INT = IWK_TRIAL + MAXE       # length of iwk
