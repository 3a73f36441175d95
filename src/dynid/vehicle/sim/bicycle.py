"""The linear bicycle model of the same car: axle cornering stiffnesses and understeer gradient.

Classic model (`bicycle`). From the static axle loads (rest state) and the tire's cornering
stiffness at each wheel's static load (MagicFormula.cornering_stiffness), with L the
wheelbase, m_f, m_r the axle loads as masses (Fz / g), m = m_f + m_r, a = L m_r / m and
b = L m_f / m the centre of mass behind the front and ahead of the rear axle, C_f, C_r the
axle cornering stiffnesses:

  understeer gradient  K = m_f / C_f - m_r / C_r          rad per m/s^2 (road-wheel angle)
  yaw-rate gain        r / delta = v / (L + K v^2)
  steady steer         delta = (L / v^2 + K) a_y

Extended model (`cornering_bicycle`): the first-order effects the simulated car adds, each
linear in the lateral acceleration a_y (> 0 turning left; forces, angles and positions y
> 0 to the left), from the same parameters at the speed v:

  C_f, C_r  the cornering stiffnesses at the straight-running loads at v (aero lift and
            pitch moment move them)
  t         pneumatic trail: each tire's aligning moment is -t Fy (MagicFormula.t0)
  eps_f,r   roll steer (rad per m/s^2): the kinematic tables' d(steer)/du at the operating
            point times the damper travel du/da_y, Ky-weighted over the axle
  eta_f,r   toe x load transfer (N per m/s^2): sum over the axle of dKy/dFz dFz/da_y h0, h0
            the static toe; a toe-in's opposed forces stop cancelling when the loads shift
  N         yaw moment of the tires' forces along the car (N.m per m/s^2), N = -sum y_i dFl_i/da_y
            with Fl_i = Fx_i - h0_i Fy_i (the lateral force of a wheel toed by h0 has a component
            along the car) and, from each wheel's spin equation at constant speed (rho the loaded
            radius), Fx_i = T_i / rho_i - fr Fz_i - N_i r20_i - t Fy_i r21_i / rho_i: the drive
            torque shared equally by the front wheels, rolling resistance, the normal force N_i
            acting off the wheel's vertical (the template's contact point lies on the hub's
            axis z15, which the caster table and the pitch tilt: r20 = x15 . z0) and the
            aligning moment's component along the tilted axle (r21 = y15 . z0)
  X_f       the front wheels' drive force (drag plus the rear wheels' resistance), turned with
            the steering: a lateral force X_f delta at the front axle
  Y, M      aerodynamic side force and yaw moment at the reference point, linear in its
            sideslip beta_ref = beta + x_ref r / v: Y = q S Cy'(0) beta_ref, M = q S L Cn'(0)
            beta_ref + x_ref Y about the centre of mass, q = rho v^2 / 2

Steady state: the axle forces F_f = C_f (delta + eps_f a_y - gamma_f) + eta_f a_y and F_r =
C_r (eps_r a_y - gamma_r) + eta_r a_y (gamma the velocity direction at the axle), with

  F_f + F_r + X_f delta + Y = m a_y,   (a - t) F_f - (b + t) F_r + a X_f delta + N a_y + M = 0.

Without X_f and the aerodynamics this is closed-form (the `understeer` property):

  K = [m (b + t) - N] / (L C_f) - [m (a - t) + N] / (L C_r) - (eps_f - eps_r) - eta_f / C_f + eta_r / C_r

and with them the same linear equations are solved (`understeer_at(v)`, `yaw_rate_gain`). The
derivatives du/da_y, dFz/da_y, d(r20)/da_y... come from quasi-static cornering equilibria
solved with the engine's inverse dynamics (`cornering_response`), independently of the
simulator's compiled forward dynamics. The tire model has no camber terms, so the camber
tables do not enter.

With the yaw inertia Iz at the centre of mass, `lateral_gain` is the 2-DOF (lateral velocity,
yaw rate) frequency response a_y / delta at f Hz with the same terms (roll quasi-static).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ...dynamics import Model, Wrench
from ...model.tree import Tree
from ..aero import Aerodynamics, aero_wrench, reference_point
from ..geometry import CarGeometry, side
from ..statics import RestState
from ..tables import KinematicTables
from ..template import CHASSIS, DAMPERS, TIRES, WHEELS


@dataclass(frozen=True)
class Bicycle:
    """Linear single-track model; the fields after yaw_inertia are the extended model's (module doc)."""

    wheelbase: float
    mass_front: float
    mass_rear: float
    cf: float
    cr: float
    yaw_inertia: float = 0.0
    trail: float = 0.0
    roll_steer: tuple[float, float] = (0.0, 0.0)  # (front, rear), rad per m/s^2
    toe_force: tuple[float, float] = (0.0, 0.0)  # (front, rear), N per m/s^2
    yaw_moment: float = 0.0  # N, N.m per m/s^2
    drive: float = 0.0  # X_f, N
    aero_side: float = 0.0  # q S Cy'(0) / v^2, N s^2/m^2 per rad
    aero_yaw: float = 0.0  # (q S L Cn'(0) + x_ref q S Cy'(0)) / v^2, N s^2/m per rad
    aero_arm: float = 0.0  # x_ref: the aerodynamic reference point ahead of the centre of mass, m

    @property
    def mass(self) -> float:
        return self.mass_front + self.mass_rear

    @property
    def axle_forces(self) -> tuple[float, float]:
        """Steady (F_f, F_r) per unit a_y (kg) without X_f and aerodynamics: the lateral and yaw balances."""
        m, L, t, N = self.mass, self.wheelbase, self.trail, self.yaw_moment
        b = L * self.mass_front / m
        return (m * (b + t) - N) / L, (m * (L - b - t) + N) / L

    @property
    def understeer(self) -> float:
        """K without X_f and the aerodynamics, rad per m/s^2 (closed form, module doc)."""
        ff, fr = self.axle_forces
        (ef, er), (hf, hr) = self.roll_steer, self.toe_force
        return ff / self.cf - fr / self.cr - (ef - er) - hf / self.cf + hr / self.cr

    def understeer_at(self, v: float) -> float:
        """K at the speed v with every term: delta / a_y - L / v^2 in the steady state."""
        return (v / self.yaw_rate_gain(v) - self.wheelbase) / (v * v)

    def yaw_rate_gain(self, v: float) -> float:
        """r / delta (1/s) at speed v (m/s), delta the road-wheel angle: v / (L + K v^2)."""
        if self.drive == 0.0 and self.aero_side == 0.0 and self.aero_yaw == 0.0:
            return v / (self.wheelbase + self.understeer * v * v)
        bike = self if self.yaw_inertia > 0 else replace(self, yaw_inertia=1.0)  # the steady state does not need it
        A, B, _, _ = bike._linear(v)
        return float(-np.linalg.solve(A, B)[1])

    def steer_for(self, v: float, ay: float) -> float:
        return (self.wheelbase / v**2 + self.understeer) * ay

    def _derivatives(self, x: np.ndarray, delta: float, v: float) -> tuple[float, float, float]:
        """(vy', r', a_y) at the state x = (vy, r) (vy at the centre of mass); roll quasi-static."""
        m, L, t = self.mass, self.wheelbase, self.trail
        a = L * self.mass_rear / m
        b = L - a
        vy, r = x
        beta_ref = (vy + self.aero_arm * r) / v
        side_force, aero_moment = self.aero_side * v * v * beta_ref, self.aero_yaw * v * v * beta_ref
        f0 = self.cf * (delta - (vy + a * r) / v)
        r0 = -self.cr * (vy - b * r) / v
        phi_f = self.cf * self.roll_steer[0] + self.toe_force[0]
        phi_r = self.cr * self.roll_steer[1] + self.toe_force[1]
        push = self.drive * delta
        ay = (f0 + r0 + push + side_force) / (m - phi_f - phi_r)  # the a_y-dependent forces solved with m a_y
        ff, fr = f0 + phi_f * ay, r0 + phi_r * ay
        yaw = (a - t) * ff - (b + t) * fr + a * push + self.yaw_moment * ay + aero_moment
        return ay - v * r, yaw / self.yaw_inertia, ay

    def _linear(self, v: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """(A, B, C, D) of x' = A x + B delta, a_y = C x + D delta (the model is linear: unit evaluations)."""
        e = np.eye(2)
        cols = [self._derivatives(e[i], 0.0, v) for i in range(2)]
        *B, D = self._derivatives(np.zeros(2), 1.0, v)
        return np.array([c[:2] for c in cols]).T, np.array(B), np.array([c[2] for c in cols]), D

    def lateral_gain(self, v: float, f: float) -> float:
        """|a_y / delta| (m/s^2 per rad) of the 2-DOF model at f Hz (f = 0: steady state)."""
        A, B, C, D = self._linear(v)
        s = 2j * np.pi * f
        x = np.linalg.solve(s * np.eye(2) - A, B)
        return float(abs(C @ x + D))


def bicycle(loads: np.ndarray, tires, wheelbase: float, g: float = 9.81, yaw_inertia: float = 0.0) -> Bicycle:
    """The classic model. loads (4,) static vertical loads rl rr fl fr (N); tires: 4 MagicFormula;
    yaw_inertia kg.m^2 at the centre of mass (for the frequency response only)."""
    c = [t.cornering_stiffness(float(f)) for t, f in zip(tires, loads, strict=True)]
    return Bicycle(wheelbase, (loads[2] + loads[3]) / g, (loads[0] + loads[1]) / g, c[2] + c[3], c[0] + c[1],
                   yaw_inertia)


# ----- quasi-static cornering ---------------------------------------------------------------

KN = 1000.0  # loads in kN in the Newton unknowns (as rest_state)


@dataclass(frozen=True)
class CornerState:
    """Per corner (rl rr fl fr) at a quasi-static state: damper travel u (m), vertical ground force
    (N), tire spring force kt q (N, the Magic Formula's load), loaded radius rho (m), and the ground
    normal's components r20 = x15 . z0, r21 = y15 . z0 in the tire frame."""

    u: np.ndarray
    load: np.ndarray
    spring: np.ndarray
    rho: np.ndarray
    r20: np.ndarray
    r21: np.ndarray


@dataclass(frozen=True)
class Turn:
    """A steady turn at the instant q1 = q2 = q4 = 0: speed (m/s) along y0, lateral acceleration a_y,
    the tires' lateral forces (4,) N at the contact points, a constant wrench on the chassis (6,)
    in frame 6 at `point` (the aerodynamic lift and pitch moment), wheel radius for the spin rates."""

    speed: float
    ay: float
    lateral: np.ndarray
    chassis: np.ndarray
    point: np.ndarray
    wheel_radius: float


def _unpack(tables: KinematicTables, n_joints: int, x: np.ndarray) -> np.ndarray:
    """q (N, n) from the unknowns x (N, 15) = (q3, q5, q6, 4 dampers, 4 tire deflections, 4 loads kN)."""
    q = np.zeros((x.shape[0], n_joints))
    q[:, [2, 4, 5]] = x[:, :3]
    q[:, np.array(DAMPERS) - 1] = x[:, 3:7]
    q[:, np.array(TIRES) - 1] = x[:, 7:11]
    zero = np.zeros_like(q)
    return tables.joints(q, zero, zero, 0.0)[0]


def _residual(model: Model, tables: KinematicTables, turn: Turn, x: np.ndarray) -> np.ndarray:
    """Residuals (N, 15): the z, pitch, roll, damper and tire equations and the contact points' heights."""
    n = x.shape[0]
    q = _unpack(tables, model.tree.n, x)
    qd, qdd = np.zeros_like(q), np.zeros_like(q)
    qd[:, 1], qd[:, 3], qdd[:, 0] = turn.speed, turn.ay / turn.speed, -turn.ay  # centripetal: towards -x0
    qd[:, np.array(WHEELS) - 1] = turn.speed / turn.wheel_radius
    ws = [Wrench(CHASSIS, turn.chassis, point=tuple(turn.point), frame=CHASSIS)]
    for i, t in enumerate(TIRES):  # ground force at the contact point, frame 0: lateral (left = -x0) and load
        w = np.zeros((n, 6))
        w[:, 0], w[:, 2] = -turn.lateral[i], x[:, 11 + i] * KN
        ws.append(Wrench(t, w, frame=0))
    rows = np.array([3, 5, 6, *DAMPERS, *TIRES]) - 1
    tau = model.inverse_dynamics(q, qd, qdd, wrenches=ws)
    z = model.transforms(q)[:, np.array(TIRES), 2, 3]
    return np.concatenate([tau[:, rows] / KN, z * 1e3], axis=1)


def _newton(fun, x0: np.ndarray, tol: float = 1e-12, step: float = 1e-7) -> np.ndarray:
    """Newton's method with a forward-difference Jacobian, all columns in one batched call of fun."""
    x = x0.copy()
    for _ in range(20):
        R = fun(np.vstack([x, x + step * np.eye(x.size)]))
        dx = np.linalg.solve((R[1:] - R[0]).T / step, -R[0])
        x = x + dx
        if np.abs(dx).max() < tol:
            return x
    raise RuntimeError("quasi-static cornering: Newton's method did not converge")


def quasi_static(model: Model, tables: KinematicTables, rest: RestState, turn: Turn) -> CornerState:
    """The car's equilibrium in the steady turn (the car's inertia at the centripetal acceleration and
    the spinning wheels' gyroscopic moments from the inverse dynamics; steering wheel straight)."""
    x0 = np.concatenate([rest.q[[2, 4, 5]], rest.q[np.array(DAMPERS) - 1], rest.q[np.array(TIRES) - 1],
                         rest.loads / KN])
    x = _newton(lambda X: _residual(model, tables, turn, X), x0)
    q = _unpack(tables, model.tree.n, x[None])[0]
    R = model.transforms(q)[np.array(TIRES), :3, :3]
    deflection = x[7:11]
    kt = np.array([model.tree.values[f"K{t}"] for t in TIRES])
    return CornerState(x[3:7], x[11:] * KN, kt * deflection, turn.wheel_radius - deflection, R[:, 2, 0], R[:, 2, 1])


# ----- the extended model ------------------------------------------------------------------

@dataclass(frozen=True)
class Car:
    """What the extended model is computed from (a CarSimulator has all of it)."""

    tree: Tree
    tables: KinematicTables
    rest: RestState
    tires: tuple
    geometry: CarGeometry
    aero: Aerodynamics | None  # None: no aerodynamic forces


def _aero_terms(car: Car, model: Model, speed: float, x_cg: float) -> tuple[np.ndarray, np.ndarray, tuple]:
    """(lift and pitch wrench in frame 6 (6,), its point, (drag N, aero_side, aero_yaw, x_ref)) at speed."""
    if car.aero is None:
        return np.zeros(6), np.zeros(3), (0.0, 0.0, 0.0, 0.0)
    aero = car.aero
    point = reference_point(car.geometry) if aero.point is None else np.asarray(aero.point, dtype=float)
    qd = np.zeros(car.tree.n)
    qd[1] = speed
    w = np.array(aero_wrench(model, car.rest.q, qd, aero, car.geometry).values).reshape(6)
    drag = -w[2]  # frame 6: z forward
    w[2] = 0.0  # the drag and the front wheels' drive act at ground level: their moments cancel
    h = 1e-4
    dc = (aero.coefficients(np.array([h]))[0] - aero.coefficients(np.array([-h]))[0]) / (2 * h)
    qs = 0.5 * aero.rho * aero.area
    x_ref = float(point[2]) - x_cg
    return w, point, (drag, qs * dc[1], qs * (aero.length * dc[5] + x_ref * dc[1]), x_ref)


def _along(car: Car, st: CornerState, fy: np.ndarray, toe: np.ndarray, drive: float) -> np.ndarray:
    """Fl_i (4,): the tires' forces along the car (module doc); drive: the front axle's drive force."""
    t = np.array([tt.t0 for tt in car.tires])
    fr = np.array([tt.fr for tt in car.tires])
    torque = np.array([0.0, 0.0, 0.5, 0.5]) * drive * np.mean(st.rho[2:])
    fx = torque / st.rho - fr * st.spring - st.load * st.r20 - t * fy * st.r21 / st.rho
    return fx - toe * fy


def cornering_bicycle(classic: Bicycle, car: Car, speed: float, ay: float = 0.5) -> Bicycle:
    """The extended model (module doc) at `speed` m/s, derivatives by central differences at +-ay."""
    model = Model(car.tree)
    m, L = classic.mass, classic.wheelbase
    chassis, point, (drag, a_side, a_yaw, x_ref) = _aero_terms(car, model, speed, L * classic.mass_front / m)

    def state(a: float, lateral: np.ndarray) -> CornerState:
        turn = Turn(speed, a, lateral, chassis, point, car.geometry.wheel_radius)
        return quasi_static(model, car.tables, car.rest, turn)

    straight = state(0.0, np.zeros(4))
    ky = np.array([t.cornering_stiffness(float(f)) for t, f in zip(car.tires, straight.spring, strict=True)])
    dky = np.array([t.cornering_stiffness_slope(float(f)) for t, f in zip(car.tires, straight.spring, strict=True)])
    cf, cr = ky[2:].sum(), ky[:2].sum()
    trail = float(np.mean([t.t0 for t in car.tires]))
    base = Bicycle(L, classic.mass_front, classic.mass_rear, cf, cr, classic.yaw_inertia, trail)
    f_front, f_rear = base.axle_forces
    split = np.concatenate([f_rear * ky[:2] / cr, f_front * ky[2:] / cf])  # N per m/s^2 of a_y, shared by Ky
    plus, minus = state(ay, split * ay), state(-ay, -split * ay)

    def rate(f) -> np.ndarray:  # d/da_y of a per-corner quantity
        return (f(plus) - f(minus)) / (2.0 * ay)

    fr_rear = np.array([t.fr for t in car.tires[:2]])
    drive = drag + float(np.sum(fr_rear * straight.spring[:2] + straight.load[:2] * straight.r20[:2]))
    steer = [car.tables.table(k, "steering").derivatives(straight.u[k], 0.0) for k in range(4)]
    toe = np.array([float(s[0][0]) for s in steer])
    wheel_steer = np.array([float(s[1][0]) for s in steer]) * rate(lambda s: s.u)  # rad per m/s^2, > 0 left
    eps = [float(np.average(wheel_steer[ax], weights=ky[ax])) for ax in (slice(2, 4), slice(0, 2))]
    dfz = rate(lambda s: s.spring)
    eta = [float(np.sum(dky[ax] * dfz[ax] * toe[ax])) for ax in (slice(2, 4), slice(0, 2))]
    dfx = (_along(car, plus, split * ay, toe, drive) - _along(car, minus, -split * ay, toe, drive)) / (2 * ay)
    y_left = np.array([-side(k) * car.geometry.axle(k).half_track for k in range(4)])
    return Bicycle(L, classic.mass_front, classic.mass_rear, cf, cr, classic.yaw_inertia, trail,
                   (eps[0], eps[1]), (eta[0], eta[1]), -float(y_left @ dfx), drive, a_side, a_yaw, x_ref)
