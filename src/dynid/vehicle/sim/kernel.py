"""The simulator's per-step kernel: car forward dynamics, tires, driver, RK4 loop.

This file is compiled by `car.py` as one cached module, the same for every vehicle: the three
functions generated from a car's tree (numba_backend.native_functions: straight-line code compiled
from LLVM IR, no Numba typing) are run-time arguments, `models` = their addresses in this order,
called through `call_model(models[i], (arrays...))` (llvm_code.address_call):

  car_kin(q, qd, out)          poses and twists of the tire frames and frame 6 (KIN_* layout)
  car_idm(q, qd, qdd, wrench, out)   inverse dynamics with the tree's numeric parameters and
                               wrench sites: 4 tire frames (origin, own axes), aero on link 6
  car_inertia(q, out)          the rows of the inertia matrix M(q) of the free joints (composite
                               bodies), flat (NF, 42): out[NF_ROW * i + c] = M[FREE[i] - 1, c] on
                               the free and tabulated columns c (the others are left 0)

So a new vehicle compiles only its three models (well under a second of LLVM), and the kernel's
own compile (seconds of Numba typing) happens once per dynid version, and can run in another
process while the vehicle is loaded (car.prebuild_kernel).

Forward dynamics (DESIGN, issue 5). Free joints f: x y z yaw pitch roll, the 4 dampers,
the 4 wheel spins. Prescribed: the tabulated joints (steering, camber, caster, kingpin:
functions of the corner's damper travel u and the steering-wheel angle h), with
qdd_p = F qdd_f + b by the chain rule (F = df/du on the damper column). Constant joints
0. Tire deflections: the contact condition (tire frame origin on the ground) gives q and
qd in closed form; the tire links are massless and terminal, so their acceleration does
not enter. Then

  (M_ff + M_fp F) qdd_f = tau_f - h_f,   h = IDM(q, qd, [0, b], wrenches)

solved by Gaussian elimination (lu_solve), with tau_f = 0 except on the wheel spins (drive
+ brake torque, plus the ground's moment about the axle at the wheel centre, which in the
tree acts on the hub: see car_identification). The prescribed joints' actuators act on
their own joints only.

State y (NY): qf (14), qdf (14), tire relaxation ux (4), uy (4), speed-controller
integral, steering-wheel angle and rate (2). Free joint order: FREE (1-based).
"""

from __future__ import annotations

import math

import numpy as np

from dynid.vehicle.sim.interp import eval_ppoly
from dynid.vehicle.sim.tires import magic_formula
from dynid.vehicle.table_poly import eval_table
from dynid.vehicle.template import DAMPERS, FREE_JOINTS, WHEELS, damper, tabulated, tire, wheel

FREE = (*FREE_JOINTS, *DAMPERS, *WHEELS)  # 1, ..., 6, 9, 18, 27, 36, 14, 23, 32, 41
# each corner's columns of q (frame j in column j - 1), from the template's corner frames: the damper, the first
# tabulated joint (steering; camber, caster, kingpin follow it), the wheel, the tire
DAMPER_COL = tuple(damper(k) - 1 for k in range(4))
TABLE_COL = tuple(tabulated(k)[0] - 1 for k in range(4))
WHEEL_COL = tuple(wheel(k) - 1 for k in range(4))
TIRE_COL = tuple(tire(k) - 1 for k in range(4))
NF = 14
NY = 39
Y_UX, Y_UY, Y_INT, Y_H, Y_HD = 28, 32, 36, 37, 38
# kinematics outputs: per corner 18 values (R15 row-major 9, P15 3, w15 3, v15 3), then frame 6 (v6 3, w6 3)
KIN_CORNER = 18
KIN_6 = 72
NKIN = 78
NF_ROW = 42  # columns of car_inertia's rows
# scalar parameters
P_R0, P_G, P_MASS, P_RATIO, P_WB, P_US, P_KP, P_KI, P_TDMAX, P_TDMIN = 0, 1, 2, 3, 4, 5, 6, 7, 8, 9
P_WS, P_ZS, P_RHO, P_AREA, P_LEN, P_VMIN, P_AREF, P_AERO_ON, P_HORIZ, P_ROLL = 10, 11, 12, 13, 14, 15, 16, 19, 20, 21
P_VLOW = 22
P_FS = 23  # the dampers' dry friction fs9, fs18, fs27, fs36 (N), then its speed scale v_s (m/s)
P_FVS = 27
NPAR = 28
# per-corner tire parameters after the Magic Formula ones: kt, ct
# recorded per sample (REC): h, hd, hdd, spin torques 4, contact flags 4, slips kappa 4, alpha 4
NREC = 19
# manoeuvre kinds
M_CONST, M_SINE, M_BRAKE, M_SPIRAL, M_STEP, M_LANE, M_ACCEL, M_FISHHOOK, M_RANDOM = 0, 1, 2, 3, 4, 5, 6, 7, 8
M_TABLE = 9
MAN_TABLE = 10  # a table manoeuvre's samples start here: steering wheel (rad), acceleration (m/s^2), speed (m/s)
# status codes
S_OK, S_TABLE, S_NONFINITE = 0, 1, 2
# the generated models, in the order of `models`
MODELS = ("car_kin", "car_idm", "car_inertia")
KIN, IDM, INERTIA = 0, 1, 2


def smoothstep(x):
    if x <= 0.0:
        return 0.0
    if x >= 1.0:
        return 1.0
    return x * x * x * (10.0 + x * (-15.0 + 6.0 * x))


def path_offset(man, s):
    """Left offset of the lane-change centreline at the distance s along y0 (quintic transitions)."""
    s1, s2, s3, s4, D = man[5], man[6], man[7], man[8], man[4]
    if s < s1:
        return 0.0
    if s < s2:
        return D * smoothstep((s - s1) / (s2 - s1))
    if s < s3:
        return D
    if s < s4:
        return D * (1.0 - smoothstep((s - s3) / (s4 - s3)))
    return 0.0


def fishhook_angle(man, t):
    """The fishhook's steering-wheel angle t s after its start: up to A, a dwell, down to -A, held, back to 0, each
    move at the mean rate man[4] (a quintic: no step in the robot's acceleration)."""
    A, rate, dwell, hold = man[3], man[4], man[5], man[6]
    t1 = A / rate
    t2 = t1 + dwell
    t3 = t2 + 2.0 * A / rate
    t4 = t3 + hold
    if t < t1:
        return A * smoothstep(t / t1)
    if t < t2:
        return A
    if t < t3:
        return A * (1.0 - 2.0 * smoothstep((t - t2) / (t3 - t2)))
    if t < t4:
        return -A
    return -A * (1.0 - smoothstep((t - t4) / t1))


def random_angle(man, t):
    """The random steer's steering-wheel angle t s after its start: man[5] sines at k f_max / n (k = 1..n) with
    Schroeder's phases (a flat spectrum up to f_max of low crest factor), RMS man[3], faded in over a second."""
    n = int(man[5])
    h = 0.0
    for k in range(1, n + 1):
        h += math.sin(2.0 * math.pi * k * man[4] / n * t - math.pi * k * (k - 1) / n)
    return man[3] * math.sqrt(2.0 / n) * h * smoothstep(t)


def table_value(man, column, t):
    """A table manoeuvre's column (0 steering wheel, 1 acceleration demand, 2 speed target) at t s: linear between
    its samples man[3] s apart (man[4] of them), held after the last."""
    n = int(man[4])
    x = t / man[3]
    if x <= 0.0:
        i, f = 0, 0.0
    elif x >= n - 1:
        i, f = n - 2, 1.0
    else:
        i = int(x)
        f = x - i
    base = MAN_TABLE + column * n
    return man[base + i] + f * (man[base + i + 1] - man[base + i])


def driver(t, y, v, par, man, out):
    """Steering-wheel target, total drive torque and the brake torque per wheel.

    man: [kind, v_ref, t0, a, b, c, d, e, f, g]; out[0] h_ref, out[1] drive torque (front axle, N.m),
    out[2:6] brake torque magnitude on the wheels rl rr fl fr (N.m, >= 0), out[6] speed error.
    """
    kind = int(man[0])
    # a table's columns as kind - M_TABLE + c (0 + c there), not the literals c: numba would compile table_value
    # once per literal argument (three times on a cold start)
    col = kind - M_TABLE
    vref = man[1]
    t0 = man[2]
    h_ref = 0.0
    brake = 0.0
    drive_on = 1.0
    if kind == M_SINE:
        if t > t0:
            taper = smoothstep((t - t0) * man[4])  # the amplitude grows over the first period
            h_ref = man[3] * taper * math.sin(2.0 * math.pi * man[4] * (t - t0))
    elif kind == M_BRAKE:
        if t > t0:
            on = smoothstep((t - t0) / man[5]) * smoothstep((v - man[6]) / 1.0)
            brake = on * man[3]
            drive_on = 1.0 - smoothstep((t - t0) / man[5])
    elif kind == M_SPIRAL:
        if t > t0:
            h_ref = min(man[3] * (t - t0), man[4])
    elif kind == M_STEP:
        if t > t0:
            h_ref = man[3] * smoothstep((t - t0) / man[4])
    elif kind == M_LANE:
        psi = y[3]
        Lp = max(man[9] * v, 5.0)
        px = y[0] - Lp * math.sin(psi)
        py = y[1] + Lp * math.cos(psi)
        e = path_offset(man, py) + px
        h_ref = par[P_RATIO] * (par[P_WB] + par[P_US] * v * v) * 2.0 * e / (Lp * Lp)
    elif kind == M_FISHHOOK and t > t0:
        h_ref = fishhook_angle(man, t - t0)
    elif kind == M_RANDOM and t > t0:
        h_ref = random_angle(man, t - t0)
    elif kind == M_TABLE:
        h_ref = table_value(man, col, t)
    mR = par[P_MASS] * par[P_R0]
    ff = (par[P_MASS] * par[P_G] * 0.012 + 0.5 * par[P_RHO] * par[P_AREA] * 0.31 * v * v * par[P_AERO_ON]) * par[P_R0]
    if kind == M_ACCEL and t > t0:  # the speed target ramps at man[3] m/s^2 up to man[4] m/s, its force fed forward
        ramp = smoothstep((t - t0) / man[5])
        vref = min(vref + man[3] * max(t - t0 - 0.5 * man[5], 0.0), man[4])
        ff += mR * man[3] * ramp * smoothstep((man[4] - v) / 1.0)
    if kind == M_TABLE:  # the speed target and its acceleration fed forward; a negative torque is braking
        vref = table_value(man, col + 2, t)
        ff += mR * table_value(man, col + 1, t)
    err = vref - v
    td = ff + mR * (par[P_KP] * err + par[P_KI] * y[Y_INT])
    if kind == M_TABLE and td < 0.0:
        brake = -td
        td = 0.0
    td = min(max(td, par[P_TDMIN]), par[P_TDMAX]) * drive_on
    out[0] = h_ref
    out[1] = td
    share = man[4] if kind == M_BRAKE else man[5]  # a table's front share; brake is 0 but for the two
    out[2] = out[3] = brake * (1.0 - share) * 0.5
    out[4] = out[5] = brake * share * 0.5
    out[6] = err if drive_on > 0.5 else 0.0
    return 0


def reduced_inertia(Af, F, M):
    """M (NF, NF) = M_ff + M_fp F from the free rows Af of M: column i is M e_FREE[i] plus, for a damper,
    M times the tabulated joints' chain-rule column F[k, :4]."""
    for i in range(NF):
        c = FREE[i] - 1
        for j in range(NF):
            M[j, i] = Af[NF_ROW * j + c]
    for k in range(4):
        for n in range(4):
            c = TABLE_COL[k] + n
            f = F[k, n]
            for j in range(NF):
                M[j, 6 + k] += Af[NF_ROW * j + c] * f
    return 0


def lu_solve(M, x):
    """x <- M^-1 x by Gaussian elimination with partial pivoting, in place (M is overwritten): a 14 x 14
    system without the allocations and copies of np.linalg.solve. Returns 1 if M is singular."""
    n = x.size
    for c in range(n):
        p = c
        big = abs(M[c, c])
        for r in range(c + 1, n):
            if abs(M[r, c]) > big:
                big = abs(M[r, c])
                p = r
        if big == 0.0:
            return 1
        if p != c:
            for k in range(c, n):
                M[c, k], M[p, k] = M[p, k], M[c, k]
            x[c], x[p] = x[p], x[c]
        inv = 1.0 / M[c, c]
        for r in range(c + 1, n):
            f = M[r, c] * inv
            if f != 0.0:
                for k in range(c + 1, n):
                    M[r, k] -= f * M[c, k]
                x[r] -= f * x[c]
    for c in range(n - 1, -1, -1):
        acc = x[c]
        for k in range(c + 1, n):
            acc -= M[c, k] * x[k]
        x[c] = acc / M[c, c]
    return 0


def derivative(t, y, dy, par, tire, man, XB, YB, TNX, TNY, C, ax, aC, models,
               q, qd, qdd, wr, kin, hv, Af, M, x, F, rhs, tab, ctl, tf, record, krow, RQ, RQD, RQDD, RW, RR):
    """dy/dt at (t, y); with record, the sample's q, qd, qdd, wheel wrenches and controls go to row krow."""
    status = S_OK
    for i in range(42):
        q[i] = 0.0
        qd[i] = 0.0
        qdd[i] = 0.0
    for i in range(NF):
        q[FREE[i] - 1] = y[i]
        qd[FREE[i] - 1] = y[NF + i]
    h = y[Y_H]
    hd = y[Y_HD]
    # tabulated joints (chain rule on the damper travel and the steering-wheel angle)
    for k in range(4):
        u = q[DAMPER_COL[k]]
        ud = qd[DAMPER_COL[k]]
        for n in range(4):
            if eval_table(XB, YB, TNX, TNY, C, 4 * k + n, u, h, tab) != 0:
                status = S_TABLE
            j = TABLE_COL[k] + n
            q[j] = tab[0]
            qd[j] = tab[1] * ud + tab[2] * hd
            F[k, n] = tab[1]
            # b without the hdd term (added once the driver has decided hdd)
            qdd[j] = tab[3] * ud * ud + 2.0 * tab[4] * ud * hd + tab[5] * hd * hd
            F[k, 4 + n] = tab[2]
    # tire deflections from the contact condition, at q15 = qd15 = 0 first
    call_model(models[KIN], (q, qd, kin))
    v6 = kin[KIN_6 + 2]  # forward speed of O6
    driver(t, y, v6, par, man, ctl)
    hdd = par[P_WS] * par[P_WS] * (ctl[0] - h) - 2.0 * par[P_ZS] * par[P_WS] * hd
    for k in range(4):
        for n in range(4):
            qdd[TABLE_COL[k] + n] += F[k, 4 + n] * hdd
    R0 = par[P_R0]
    for k in range(4):
        o = KIN_CORNER * k
        r20, r21, r22 = kin[o + 6], kin[o + 7], kin[o + 8]
        pz = kin[o + 11]
        w0, w1 = kin[o + 12], kin[o + 13]
        pen = -pz / r22
        vc0 = kin[o + 15] + w1 * pen
        vc1 = kin[o + 16] - w0 * pen
        vc2 = kin[o + 17]
        pend = -(vc0 * r20 + vc1 * r21 + vc2 * r22) / r22
        kt = tire[k, 25]
        ct = tire[k, 26]
        Fz = kt * pen + ct * pend
        contact = pen > 0.0 and Fz > 0.0
        jt = TIRE_COL[k]
        jw = WHEEL_COL[k]
        omega = qd[jw]
        # ground axes in frame 15: normal n = (r20, r21, r22); heading xg = x15 made horizontal; yg = n x xg
        xn = 1.0 - r20 * r20
        inv = 1.0 / math.sqrt(xn * xn + (r20 * r21) ** 2 + (r20 * r22) ** 2)
        xg0, xg1, xg2 = xn * inv, -r20 * r21 * inv, -r20 * r22 * inv
        yg0 = r21 * xg2 - r22 * xg1
        yg1 = r22 * xg0 - r20 * xg2
        yg2 = r20 * xg1 - r21 * xg0
        Vx = vc0 * xg0 + vc1 * xg1 + vc2 * xg2
        Vy = vc0 * yg0 + vc1 * yg1 + vc2 * yg2
        aVx = abs(Vx)
        sx = tire[k, 20]
        sy = tire[k, 21]
        Re = R0 - pen / 3.0
        Vsx = Vx - omega * Re
        Vsy = Vy
        ux = y[Y_UX + k]
        uy = y[Y_UY + k]
        kappa = ux / sx
        alpha = math.atan(-uy / sy)
        for c in range(6):
            wr[k, c] = 0.0
        if contact:
            q[jt] = pen
            qd[jt] = pend
            # the Magic Formula's load is the tire spring's force; Fx, Fy act in the ground plane and the
            # normal force N is what leaves the massless tire link in equilibrium along its axis z15:
            # N n.z15 + Fx xg.z15 + Fy yg.z15 = kt q + ct qd (the identification's tire equation)
            magic_formula(tire[k], Fz, kappa, alpha, tf)
            fx = tf[0] * par[P_HORIZ]
            fy = tf[1] * par[P_HORIZ]
            mz = tf[2] * par[P_HORIZ]
            N = (Fz - fx * xg2 - fy * yg2) / r22
            wr[k, 0] = fx * xg0 + fy * yg0 + N * r20
            wr[k, 1] = fx * xg1 + fy * yg1 + N * r21
            wr[k, 2] = Fz
            rho = R0 - pen
            wr[k, 4] = -tire[k, 22] * Fz * rho * math.tanh(omega * Re / 0.3) * par[P_ROLL]
            wr[k, 3] = mz * r20
            wr[k, 4] += mz * r21
            wr[k, 5] = mz * r22
            dy[Y_UX + k] = -Vsx - aVx * ux / sx
            dy[Y_UY + k] = -Vsy - aVx * uy / sy
        else:
            q[jt] = 0.0
            qd[jt] = 0.0
            dy[Y_UX + k] = -(aVx + par[P_VLOW]) * ux / sx
            dy[Y_UY + k] = -(aVx + par[P_VLOW]) * uy / sy
        if record:
            RR[krow, 7 + k] = 1.0 if contact else 0.0
            RR[krow, 11 + k] = kappa
            RR[krow, 15 + k] = alpha
    # aerodynamic wrench on link 6 at the reference point (as dynid.vehicle.aero_wrench)
    for c in range(6):
        wr[4, c] = 0.0
    if par[P_AERO_ON] != 0.0:
        p0, p1, p2 = par[P_AREF], par[P_AREF + 1], par[P_AREF + 2]
        a0, a1, a2 = kin[KIN_6 + 3], kin[KIN_6 + 4], kin[KIN_6 + 5]
        vr1 = kin[KIN_6 + 1] + a2 * p0 - a0 * p2
        vr2 = kin[KIN_6 + 2] + a0 * p1 - a1 * p0
        fwd = vr2
        left = -vr1
        V2 = fwd * fwd + left * left
        beta = 0.0 if par[P_VMIN] * par[P_VMIN] > V2 else math.atan2(left, fwd)
        qS = 0.5 * par[P_RHO] * V2 * par[P_AREA]
        # a loop index, not six literal indices: numba would compile eval_ppoly once per literal (six times on a
        # cold start); tab (the tables' scratch, read above only) holds the coefficients
        for j in range(6):
            tab[j] = eval_ppoly(ax, aC, j, beta)
        cx, cy, cz, cl, cm, cn = tab[0], tab[1], tab[2], tab[3], tab[4], tab[5]
        L = par[P_LEN]
        # ISO (x fwd, y left, z up) -> frame 6 (up, right, fwd)
        wr[4, 0] = qS * cz
        wr[4, 1] = -qS * cy
        wr[4, 2] = -qS * cx
        wr[4, 3] = qS * L * cn
        wr[4, 4] = -qS * L * cm
        wr[4, 5] = qS * L * cl
    # generalized forces: h with the free accelerations at zero
    call_model(models[IDM], (q, qd, qdd, wr, hv))
    for i in range(NF):
        rhs[i] = -hv[FREE[i] - 1]
    # the dampers' dry friction, fs tanh(qd / v_s): a smooth law, so that the force is defined at reversal
    # (a sign(qd) inside the RK4 stages chatters there); past a few v_s it is fs sign(qd)
    for k in range(4):
        rhs[6 + k] -= par[P_FS + k] * math.tanh(qd[DAMPER_COL[k]] / par[P_FVS])
    for k in range(4):
        rho = R0 - q[TIRE_COL[k]]
        my_centre = wr[k, 4] - rho * wr[k, 0]
        drive = 0.5 * ctl[1] if k >= 2 else 0.0
        spin = drive - ctl[2 + k] * math.tanh(qd[WHEEL_COL[k]] / 0.5)
        rhs[10 + k] += spin + my_centre
        if record:
            RR[krow, 3 + k] = spin
    # M_ff + M_fp F from the free joints' rows of M (one composite-body pass, not NF products M v)
    call_model(models[INERTIA], (q, Af))
    reduced_inertia(Af, F, M)
    for i in range(NF):
        x[i] = rhs[i]
    if lu_solve(M, x) != 0:
        status = S_NONFINITE
    for i in range(NF):
        dy[i] = y[NF + i]
        dy[NF + i] = x[i]
    for k in range(4):
        for n in range(4):
            qdd[TABLE_COL[k] + n] += F[k, n] * x[6 + k]
    for i in range(NF):
        qdd[FREE[i] - 1] = x[i]
    dy[Y_INT] = ctl[6]
    dy[Y_H] = hd
    dy[Y_HD] = hdd
    if record:
        for j in range(42):
            RQ[krow, j] = q[j]
            RQD[krow, j] = qd[j]
            RQDD[krow, j] = qdd[j]
        for k in range(4):
            rho = R0 - q[TIRE_COL[k]]
            RW[krow, k, 0] = wr[k, 0]
            RW[krow, k, 1] = wr[k, 1]
            RW[krow, k, 2] = wr[k, 2]
            RW[krow, k, 3] = wr[k, 3] + rho * wr[k, 1]
            RW[krow, k, 4] = wr[k, 4] - rho * wr[k, 0]
            RW[krow, k, 5] = wr[k, 5]
        RR[krow, 0] = h
        RR[krow, 1] = hd
        RR[krow, 2] = hdd
    for i in range(NY):
        if not math.isfinite(dy[i]):
            status = S_NONFINITE
    return status


def simulate(y, t0, dt, nsteps, nsub, par, tire, man, XB, YB, TNX, TNY, C, ax, aC, models, RQ, RQD, RQDD, RW, RR,
             status):
    """RK4 with nsub substeps per sample; records every sample (the first stage of its step)."""
    q = np.zeros(42)
    qd = np.zeros(42)
    qdd = np.zeros(42)
    wr = np.zeros((5, 6))
    kin = np.zeros(NKIN)
    hv = np.zeros(42)
    Af = np.zeros(NF * NF_ROW)
    M = np.zeros((NF, NF))
    x = np.zeros(NF)
    F = np.zeros((4, 8))
    rhs = np.zeros(NF)
    tab = np.zeros(6)
    ctl = np.zeros(7)
    tf = np.zeros(3)
    kst = np.zeros((4, NY))  # the four RK4 stages' dy/dt
    yt = np.zeros(NY)
    hs = dt / nsub
    # the stages in a loop around ONE call of derivative: simulate's own compiled library (optimised and emitted by
    # LLVM with derivative's code linked in) then inlines one copy of it, not four (0.1-0.2 s of a first run); the
    # arithmetic is the same (1.0 * hs == hs exactly)
    for n in range(nsteps):
        for s in range(nsub):
            t = t0 + n * dt + s * hs
            for c in range(4):
                if c == 0:
                    for i in range(NY):
                        yt[i] = y[i]
                    tc = t
                else:
                    a = 1.0 if c == 3 else 0.5
                    for i in range(NY):
                        yt[i] = y[i] + a * hs * kst[c - 1, i]
                    tc = t + a * hs
                record = c == 0 and s == 0  # a bool variable: a literal would type (and compile) derivative twice
                st = derivative(tc, yt, kst[c], par, tire, man, XB, YB, TNX, TNY, C, ax, aC, models, q, qd, qdd, wr,
                                kin, hv, Af, M, x, F, rhs, tab, ctl, tf, record, n, RQ, RQD, RQDD, RW, RR)
                if c == 0:
                    if st != S_OK:
                        status[0] = st
                        status[1] = n
                        return n
                    if n == nsteps - 1:
                        break  # the last sample is recorded; no step beyond it
            if n == nsteps - 1:
                break
            for i in range(NY):
                y[i] += hs / 6.0 * (kst[0, i] + 2.0 * kst[1, i] + 2.0 * kst[2, i] + kst[3, i])
    status[0] = S_OK
    status[1] = nsteps
    return nsteps


# ----- the generated models: called by address. Without numba the addresses are the ids of Python functions the
# simulator registers in _PYTHON_MODELS; the compiled module (car.py) replaces call_model by llvm_code.address_call.
_PYTHON_MODELS: dict = {}


def call_model(address, arrays):
    """The generated model at `address` on its arrays (plain Python: numba absent)."""
    return _PYTHON_MODELS[address](*arrays)


JITTED = ("smoothstep", "path_offset", "fishhook_angle", "random_angle", "table_value", "driver",
          "reduced_inertia", "lu_solve", "derivative", "simulate")
# called by the kernel only: compiled without Python and C entry points (numba_backend.compile_source), a
# first run's kernel compile 0.8-0.9 s of CPU less (of ~7.5: the entries of derivative's 35 arrays the most), and
# kept as LLVM IR for simulate to link (symbolic.link_only: ~1 s less, of ~5.4)
INTERNAL = (*JITTED[:-1], "eval_table", "magic_formula", "eval_ppoly")
