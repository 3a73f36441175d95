"""Joint coordinates of the car from its sensor channels.

Oracle: a known smooth trajectory of all 42 joints is turned into the noise-free channels
by `sensors.ideal_channels` (the sensor suite's definition, written independently of the
estimator); the estimator must give the trajectory back. The bounds follow from the
filter: content at <= 1 Hz through a 4th-order zero-phase Butterworth at 4 Hz keeps
|H|^2 = 1/(1 + (1/4)^8) > 1 - 2e-5, and central differences at 625 Hz are exact to
(w h)^2 / 6 < 2e-4 relative for 1 Hz; the rest is the trapezoidal integration, O(h^2).
"""

import dataclasses

import numpy as np
import pytest

import dynid
from dynid.vehicle import car_template
from dynid.vehicle.estimate import CarConditioning, estimate_joints
from dynid.vehicle.geometry import CarGeometry, demo_geometry
from dynid.vehicle.sensors import ideal_channels
from dynid.vehicle.tables import default_tables

FS = 625.0


def sine(t, amp, f, ph=0.0):
    w = 2 * np.pi * f
    return amp * np.sin(w * t + ph), amp * w * np.cos(w * t + ph), -amp * w**2 * np.sin(w * t + ph)


def integral(x, t):
    """Cumulative integral, Simpson-accurate on the fine grid used here."""
    out = np.zeros_like(x)
    out[1:] = np.cumsum((x[1:] + x[:-1]) / 2 * np.diff(t))
    return out


@pytest.fixture(scope="module")
def truth():
    return smooth_drive()


def smooth_drive(duration: float = 12.0, fast_pitch: float = 0.0, geometry: CarGeometry | None = None):
    """A known smooth trajectory of all 42 joints and its noise-free channels:
    (model, t, q, qd, qdd, wheel wrenches, channels). fast_pitch: amplitude (rad) of a 3 Hz pitch oscillation
    added to the slow one (a brake release's pitch-back has such content); geometry: where the sensors sit."""
    g = demo_geometry() if geometry is None else geometry
    model = dynid.Model(car_template(g))
    tables = default_tables(g)
    t = np.arange(0, duration, 1 / FS)
    N = len(t)
    q, qd, qdd = (np.zeros((N, 42)) for _ in range(3))
    v = 25.0
    psi, dpsi, ddpsi = sine(t, 0.1, 0.5)
    q[:, 3], qd[:, 3], qdd[:, 3] = psi, dpsi, ddpsi
    vx, vy = -v * np.sin(psi), v * np.cos(psi)  # forward at yaw psi, in frame 0 (x0 right, y0 forward)
    qd[:, 0], qd[:, 1] = vx, vy
    qdd[:, 0], qdd[:, 1] = -v * np.cos(psi) * dpsi, -v * np.sin(psi) * dpsi
    q[:, 0], q[:, 1] = integral(vx, t), integral(vy, t)
    q[:, 2], qd[:, 2], qdd[:, 2] = (a + b for a, b in zip((0.0, 0.0, 0.0), sine(t, 0.01, 0.8), strict=True))
    q[:, 4], qd[:, 4], qdd[:, 4] = (a + b for a, b in zip(sine(t, 0.01, 0.6, 1.0), sine(t, fast_pitch, 3.0),
                                                          strict=True))
    q[:, 5], qd[:, 5], qdd[:, 5] = sine(t, 0.02, 0.5)
    for k in range(4):
        b = 7 + 9 * k
        q[:, b + 1], qd[:, b + 1], qdd[:, b + 1] = sine(t, 0.02, 0.7 + 0.1 * k, k)
        w = v / 0.3 + 2.0 * np.sin(2 * np.pi * 0.3 * t)
        qd[:, b + 6], qdd[:, b + 6] = w, 2.0 * 2 * np.pi * 0.3 * np.cos(2 * np.pi * 0.3 * t)
        q[:, b + 6] = integral(w, t)
    h = sine(t, 0.5, 0.5)
    q, qd, qdd = tables.joints(q, qd, qdd, steering_wheel=h)
    # raise the car so that the tires touch the ground: z of the tire frames' origins at 0 on average
    T = model.transforms(q)
    q[:, 2] -= np.mean([T[:, f, 2, 3] for f in (15, 24, 33, 42)])
    T = model.transforms(q)
    for f in (15, 24, 33, 42):  # deflection along the tire axis putting its origin on the ground
        q[:, f - 1] = -T[:, f, 2, 3] / T[:, f, 2, 2]
    qd[:, [14, 23, 32, 41]] = np.gradient(q[:, [14, 23, 32, 41]], 1 / FS, axis=0, edge_order=2)
    qdd[:, [14, 23, 32, 41]] = np.gradient(qd[:, [14, 23, 32, 41]], 1 / FS, axis=0, edge_order=2)
    ww = np.zeros((N, 4, 6))
    ww[:, :, 2] = 4000.0 + 200 * np.sin(2 * np.pi * 0.4 * t)[:, None]
    channels = ideal_channels(model, q, qd, qdd, ww, h[0], np.zeros((N, 4)), g)
    return model, t, q, qd, qdd, ww, channels


def si(channels):
    """The channels in SI, as the io layer would deliver them (deg -> rad, km/h -> m/s, mm -> m, rev/s -> rad/s)."""
    out = {}
    for k, x in channels.items():
        if k.startswith(("imu_roll", "imu_pitch", "imu_yaw", "steer_", "camber_", "steering_wheel")):
            x = np.radians(x)
        elif k == "correvit_vx":
            x = x / 3.6
        elif k.startswith(("laser_height", "clearance")):
            x = x / 1000.0
        elif k.startswith("wheel_speed"):
            x = 2 * np.pi * x
        out[k] = x
    return out


def test_estimated_joints_match_the_trajectory(truth):
    model, t, q, qd, qdd, ww, channels = truth
    # ideal channels have no sensor dynamics: nothing to compensate
    est = estimate_joints(si(channels), FS, model, conditioning=CarConditioning(cutoff=4.0, compensate_delays=False))
    i = np.searchsorted(t, est.t[0])
    sl = slice(i, i + len(est.t))
    for j in (2, 3, 4, 5, 8, 9, 10, 11, 12, 13, 14, 26, 27, 28, 31, 32, 40, 41):
        for name, a, b in (("q", est.q, q), ("qd", est.qd, qd), ("qdd", est.qdd, qdd)):
            scale = max(np.abs(b[sl, j]).max(), 1e-3 if name == "q" else 1e-2)
            err = np.abs(a[:, j] - b[sl, j]).max() / scale
            # tire deflections are millimetres from the geometry, and their truth qdd is itself a second
            # finite difference here: 1 %; every other joint 0.5 %
            assert err < (1e-2 if j + 1 in (15, 24, 33, 42) else 5e-3), (name, j + 1, err)
    # ground velocities and accelerations (positions in the plane are defined up to a constant)
    for j in (0, 1):
        assert np.abs(est.qd[:, j] - qd[sl, j]).max() < 1e-3 * 25
        assert np.abs(est.qdd[:, j] - qdd[sl, j]).max() < 5e-3 * np.abs(qdd[:, j]).max()
    assert np.abs(est.wheel_wrenches[:, :, 2] - ww[sl, :, 2]).max() < 1e-3 * 4000


def test_o6_acceleration_does_not_depend_on_where_the_unit_sits():
    """The same motion seen by an inertial unit at O6 (dynid's default) and by one at the MuJoCo car's chassis
    centre of gravity, 1.6 m ahead of O6 and 0.24 m above it, gives the same O6 acceleration: the regressor carries
    it back to every chassis point with the estimated rotation rates, so the unit's position must drop out. The
    pitch has a 3 Hz part, where the 4 Hz filter's gain is 0.91: an angular acceleration's lever arm filtered once
    more than the rates (the estimator's old order) leaves (0.91 - 0.91^2) x 1.6 m x 1.8 rad/s^2 = 0.24 m/s^2 on the
    vertical. What may remain is the low-pass of a product against the product of low-passes: the lever term
    (2.9 m/s^2 at 3 Hz) turned by the 0.1 rad, 0.5 Hz yaw into the ground axes, whose 2.5 and 3.5 Hz sidebands the
    filter passes with gains up to 0.1 apart from the 3 Hz one: at most 0.1 x 0.1 x 2.9 = 0.03 m/s^2 (0.016 seen);
    bound 0.05 m/s^2, a fifth of the old order's error."""
    cond = CarConditioning(cutoff=4.0, compensate_delays=False)
    at_o6 = demo_geometry()
    at_cog = dataclasses.replace(at_o6, imu_position=(0.24, 0.0, 1.60))
    est = {}
    for g in (at_o6, at_cog):
        model, t, q, _, _, _, channels = smooth_drive(fast_pitch=0.005, geometry=g)
        est[g.imu_position] = estimate_joints(si(channels), FS, model, g, conditioning=cond)
    a, b = est[at_o6.imu_position], est[at_cog.imu_position]
    lever = 1.6 * 0.005 * (2 * np.pi * 3.0) ** 2
    assert lever > 2.5
    assert np.abs(a.qdd[:, :3] - b.qdd[:, :3]).max() < 0.05
    i = np.searchsorted(t, a.t[0])
    # and the pitch is the trajectory's, 3 Hz part included (0.91 of it after the filter)
    assert np.abs(b.q[:, 4] - q[i:i + len(b.t), 4]).max() < 0.1 * 0.005 + 1e-4


@pytest.mark.parametrize("compensate", [False, True])
def test_saturated_camera_samples_come_from_the_tables(truth, compensate):
    """A camera clipped at its range (a spiral steers the front wheels past the cameras' 5°) is replaced where
    it sits on a limit by the tables' value: the steering and camber joints come back as from the unclipped
    channels. Oracle: the trajectory, whose steering and camber are the tables' (smooth_drive)."""
    from dynid.vehicle.dynamics import ChannelDynamics
    from dynid.vehicle.sensors import paper_suite

    model, t, q, qd, _, _, channels = truth
    # samples: the cameras' declared pure delay (48 ms, a 5 Hz band's), undone before the tables step in; without
    # the mask's widening the clipped stretches' edges are kept and the bound below fails (3 samples would not)
    late = 30 if compensate else 0
    clipped, ranges = dict(channels), {}
    for name in ("steer_fl", "steer_fr", "camber_rl"):
        x = channels[name]
        limit = 0.5 * np.abs(x).max()  # half the samples' peak: a long stretch on each limit
        ranges[name] = (-limit, limit)
        x = np.r_[np.full(late, x[0]), x[:len(x) - late]]  # what a camera `late` samples behind writes
        clipped[name] = np.clip(x, -limit, limit)
        assert np.mean(np.abs(clipped[name]) >= limit) > 0.1
    suite = paper_suite()
    for name, r in ranges.items():
        suite = suite.replace(name, range=r)
    cond = CarConditioning(cutoff=4.0, compensate_delays=compensate)
    # ideal channels, or the three cameras declared late by a pure delay: advancing them moves the clipped
    # stretches, and the mask must follow (widened by the delay) for no clipped sample to be kept
    dynamics = {name: ChannelDynamics(delay=late / FS) for name in ranges}
    est = estimate_joints(si(clipped), FS, model, conditioning=cond, suite=suite, dynamics=dynamics)
    ref = estimate_joints(si(channels), FS, model, conditioning=CarConditioning(cutoff=4.0, compensate_delays=False))
    i = np.searchsorted(t, est.t[0])
    sl = slice(i, i + len(est.t))
    for j in (28, 37, 11):  # steer fl, steer fr, camber rl (frame numbers)
        for a, r, b in ((est.q, ref.q, q), (est.qd, ref.qd, qd)):
            scale = np.abs(b[sl, j - 1]).max()
            # the same bound as the unclipped estimate (test above): 0.5 % of the joint's scale
            assert np.abs(a[:, j - 1] - b[sl, j - 1]).max() < 5e-3 * scale, j
            assert np.abs(a[:, j - 1] - r[:, j - 1]).max() < 5e-3 * scale, j


@pytest.mark.parametrize("delay", [0.0, 0.0016, 0.0037, -0.0031, 0.5, 2.0])
def test_advance_is_linear_interpolation_with_the_ends_held(delay):
    from dynid.vehicle.estimate import advance

    x = np.random.default_rng(1).standard_normal(700)
    n = np.arange(x.size, dtype=float)
    np.testing.assert_allclose(advance(x, delay, 625.0), np.interp(n + delay * 625.0, n, x), rtol=0, atol=1e-15)


def test_chassis_rotation_is_the_iso_zyx_sequence():
    from scipy.spatial.transform import Rotation

    from dynid.vehicle.estimate import EARTH, chassis_rotation
    from dynid.vehicle.sensors import ISO_AXES

    yaw, pitch, roll = np.random.default_rng(0).uniform(-3.0, 3.0, (3, 50))
    ref = EARTH @ Rotation.from_euler("ZYX", np.c_[yaw, pitch, roll]).as_matrix() @ ISO_AXES
    np.testing.assert_allclose(chassis_rotation(yaw, pitch, roll), ref, rtol=0, atol=1e-14)


@pytest.mark.parametrize("rate", [125.0, 312.5, 625.0])  # the logger's rate a whole multiple (sensors in sync)
@pytest.mark.parametrize("fs", [625.0, 625.0000000000688])  # a CSV time column's median step gives the second
def test_the_declared_delay_is_the_mean_age_of_a_held_sample(rate, fs):
    """The hold part of a Table-1 channel's declared delay (ChannelDynamics.lag) against the sensors' own
    sample-and-hold applied to a ramp x = t: the mean of t - held(t) is the mean age of the value read;
    continuous in fs (no spurious 0.8 ms at 625 Hz)."""
    from dynid.vehicle.dynamics import ChannelDynamics
    from dynid.vehicle.sensors import SensorChannel, sample_and_hold

    c = SensorChannel("x", "m", "x", "x", "x", accuracy=0.0, bandwidth=None, resolution=0.0, range=None, rate=rate)
    t = np.arange(6250) / 625.0
    age = np.mean(t - sample_and_hold(t, rate, 625.0))
    assert abs(ChannelDynamics.table1(c).lag(fs) - age) < 1e-9 + 1e-12 * fs  # the rate's rounding, ~1e-13 s


def test_the_chassis_rotation_written_in_place_is_the_gathered_one():
    """`_rotation` (each entry written once, entries first) against `chassis_rotation` (the (N, 3, 3) product
    gathered and signed): the same NumPy operations, so equal to the bit, and laid out alike (the einsum and matmul
    that read it sum in a layout-dependent order)."""
    from dynid.vehicle.estimate import _rotation, chassis_rotation

    yaw, pitch, roll = np.random.default_rng(3).uniform(-3.0, 3.0, (3, 1000))
    ref = chassis_rotation(yaw, pitch, roll)
    got = _rotation(yaw, pitch, roll)
    np.testing.assert_array_equal(got, ref)
    assert got.strides == ref.strides


@pytest.mark.parametrize("first", [0, 1])
def test_the_compiled_carry_of_the_imu_acceleration_is_the_numpy_one(first):
    """`_acceleration`'s compiled pass (the unit's low-passed acceleration carried to O6) against its NumPy path
    (signals.derivative, np.cross, einsum), the oracle it replaced: the same products summed in the same order.
    Equal here (no multiply-add fused); a machine that fuses one moves each result by a rounding or two of the
    lever-arm terms (|R (dw x r + w x (w x r))|)."""
    import dynid.vehicle.estimate as est

    rng = np.random.default_rng(6)
    n = 3000
    t = np.arange(n) / FS
    low = np.sin(2 * np.pi * rng.uniform(0.2, 2.0, 7) * t[:, None] + rng.uniform(0, 6, 7)) * rng.uniform(0.1, 9.8, 7)
    R6 = est._rotation(*(0.3 * np.sin(2 * np.pi * f * t) for f in rng.uniform(0.1, 1.0, 3)))
    x = est._Context(FS, None, demo_geometry(), CarConditioning(), None, True, 0)
    got = est._acceleration(x, R6, low, first)
    kernel, est._carry_kernel = est._carry_kernel, None
    try:
        ref = est._acceleration(x, R6, low, first)
    finally:
        est._carry_kernel = kernel
    lever = np.abs(ref - low[:, first + 3:first + 6]).max()
    np.testing.assert_allclose(got, ref, rtol=0, atol=4 * np.finfo(float).eps * (lever + np.abs(ref).max()))


def compiled_and_numpy(kernel: str, run):
    """run() with the estimator's compiled `kernel`, then with it off (its NumPy path, the oracle)."""
    import dynid.vehicle.estimate as est

    got = run()
    compiled = getattr(est, kernel)
    setattr(est, kernel, None)
    try:
        return got, run()
    finally:
        setattr(est, kernel, compiled)


@pytest.mark.parametrize("start", [False, True])
def test_the_compiled_attitude_refinement_is_the_numpy_one(start):
    """`_attitude`'s compiled refinement (the Euler rates, their trapezoidal integrals and the inclinometers' part
    left, one pass) against its NumPy path (the products, np.stack, signals.integrate, the difference), the oracle it
    replaced: the same operations in the same order. Equal here (no multiply-add fused); a machine that fuses
    qb sp + r cp or p + u tt moves a rate by a rounding of its largest term (eps max|w|), an angle by n of them
    over the integral (n eps max|w| / fs), their derivatives by fs and fs^2 times that, through the low-passes
    (gain <= 1.1)."""
    import dynid.vehicle.estimate as est

    rng = np.random.default_rng(8)
    n = 3000
    t = np.arange(n) / FS
    waves = np.sin(2 * np.pi * rng.uniform(0.1, 2.0, 5) * t[:, None] + rng.uniform(0, 6, 5))
    ch = {"imu_roll_rate": 0.3 * waves[:, 0], "imu_pitch_rate": 0.2 * waves[:, 1], "imu_yaw_rate": 0.5 * waves[:, 2],
          "imu_roll": 0.05 * waves[:, 3], "imu_pitch": 0.04 * waves[:, 4]}
    x = est._Context(FS, None, demo_geometry(), CarConditioning(), None, True, 0)
    incl = est._inclinometers(ch)
    angles = est._lowpass(incl, x)
    # a moved pass's start (`_Unmoved`): the inclinometers' sin, cos and tan as the first refinement reads them
    first = (np.sin(angles[:, 0]), np.cos(angles[:, 0]), np.tan(angles[:, 1])) if start else None

    def attitude():
        joints = [np.zeros((n, 42), order="F") for _ in range(3)]
        R6, w6 = est._attitude(ch, x, *joints, angles, incl if start else None, first)
        return [R6, w6, *(a[:, 3:6] for a in joints)]

    got, ref = compiled_and_numpy("_euler_kernel", attitude)
    eps, w = np.finfo(float).eps, 0.5
    angle = 8 * (n * eps * w / FS + eps)
    for a, b, tol in zip(got, ref, [angle, 0.0, angle, 8 * eps * w, 8 * eps * w * FS], strict=True):
        np.testing.assert_allclose(a, b, rtol=0, atol=tol)


@pytest.mark.parametrize("deflections", [False, True])
def test_the_compiled_velocity_is_the_numpy_one(deflections):
    """`_velocity`'s compiled pass (the sensor's velocity carried to O6, its vertical part from the height's rate,
    the tire deflections before their low-pass) against its NumPy path (the signed gathers, einsum, the deflections'
    three passes), the oracle it replaced: the same operations in the same order. Equal here (no multiply-add
    fused); a machine that fuses one moves a velocity by a rounding or two of its terms (eps (|v| + |w| |pc|)),
    its integral by n of them over fs; the deflections have no product to fuse."""
    import dynid.vehicle.estimate as est
    from dynid.vehicle.sensors import paper_suite

    rng = np.random.default_rng(9)
    n = 3000
    t = np.arange(n) / FS
    waves = np.sin(2 * np.pi * rng.uniform(0.1, 2.0, 20) * t[:, None] + rng.uniform(0, 6, 20))
    g = demo_geometry()
    x = est._Context(FS, None, g, CarConditioning(), paper_suite(g), True, 0)
    ch = {"correvit_vx": 25.0 + waves[:, 0], "correvit_vy": 0.5 * waves[:, 1]}
    R6 = est._rotation(*(0.1 * waves[:, 2:5].T))
    w6 = 0.3 * waves[:, 5:8]
    pz_zz = np.concatenate([0.3 + 0.01 * waves[:, 8:12], 1.0 - 0.01 * np.abs(waves[:, 12:16])], axis=1)
    z_laser = -0.3 + 0.01 * waves[:, 16:20]

    def velocity():
        q, qd, qdd = (np.zeros((n, 42), order="F") for _ in range(3))
        qd[:, 2] = 0.05 * waves[:, 4]
        est._velocity(ch, x, q, qd, R6, w6, (qdd, pz_zz, z_laser) if deflections else None)
        return q, qd, qdd

    got, ref = compiled_and_numpy("_velocity_kernel", velocity)
    eps, v = np.finfo(float).eps, 27.0
    for a, b in zip(got, ref, strict=True):
        np.testing.assert_allclose(a[:, :2], b[:, :2], rtol=0, atol=16 * eps * v * max(1.0, n / FS))
        np.testing.assert_array_equal(a[:, 2:], b[:, 2:])  # the tires' columns (zero without deflections)
    assert np.count_nonzero(got[0][:, 14]) == (n if deflections else 0)


def test_the_corners_compiled_pass_is_signals_derivative_and_integrate():
    """`_corners` (one compiled pass) against its NumPy path (signals.derivative twice, signals.integrate, the
    columns scattered into q, qd, qdd), the oracle it replaced. The interior differences have no product to fuse:
    equal; a machine that fuses a multiply-add may move the end formulas' products (|4 x| at most, one rounding:
    4 eps max|x| / (2 h) in qd, twice that over 2 h in qdd) and each integration step (eps |running value|)."""
    import dynid.vehicle.estimate as est

    rng = np.random.default_rng(5)
    n = 2000
    t = np.arange(n) / FS
    filtered = np.sin(2 * np.pi * rng.uniform(0.2, 2.0, 45) * t[:, None] + rng.uniform(0, 6, 45)) * rng.uniform(
        0.01, 30.0, 45)
    got = [np.zeros((n, 42), order="F") for _ in range(3)]
    ref = [np.zeros((n, 42), order="F") for _ in range(3)]
    h = est._corners(filtered, FS, *got)
    kernel, est._corner_kernel = est._corner_kernel, None
    try:
        h_ref = est._corners(filtered, FS, *ref)
    finally:
        est._corner_kernel = kernel
    eps, scale = np.finfo(float).eps, np.abs(filtered).max()
    # q: an integral's n steps, one rounding each of at most its running value
    tol = [2 * n * eps * np.abs(ref[0]).max(), 16 * eps * scale * FS, 64 * eps * scale * FS**2]
    for a, b, tl in zip([*got, *h], [*ref, *h_ref], tol * 2, strict=True):
        np.testing.assert_allclose(a, b, rtol=0, atol=tl)
    assert all(np.count_nonzero(a) for a in got)  # every joint the pass writes is written


@pytest.mark.parametrize("rows", [slice(7, 1990, 10), slice(1, 1999, 3), slice(0, 2000, 10), slice(5, 2000, 7)])
@pytest.mark.parametrize("shape", [(2000,), (2000, 3)])
def test_a_derivative_on_every_kth_sample_is_signals_derivative_there(rows, shape):
    """`_derivative_at` (a coarse moved pass's accelerations, on the rows' samples alone) against signals.derivative
    on every sample, then those rows: the same two operations on the same numbers, so equal to the bit, the ends'
    one-sided formulas included (rows reaching sample 0 or N - 1)."""
    from dynid.signals import derivative
    from dynid.vehicle.estimate import _derivative_at

    x = np.random.default_rng(8).standard_normal(shape).cumsum(axis=0)
    np.testing.assert_array_equal(_derivative_at(x, FS, rows), derivative(x, FS)[rows])
    np.testing.assert_array_equal(_derivative_at(x, FS, None), derivative(x, FS))


def test_the_iso_axes_gathers_are_the_matrix_products():
    """`_ISO_GATHER` and `_ISO_ROWS` (X @ ISO_AXES and X @ ISO_AXES.T as signed gathers, `_velocity` and `_attitude`)
    against the products: a signed permutation's products are the gathered numbers, exactly."""
    from dynid.vehicle.estimate import _ISO_GATHER, _ISO_ROWS
    from dynid.vehicle.sensors import ISO_AXES

    X = np.random.default_rng(9).standard_normal((500, 3))
    for gather, M in ((_ISO_GATHER, ISO_AXES), (_ISO_ROWS, ISO_AXES.T)):
        got = np.stack([X[:, k] if sign > 0 else -X[:, k] for k, sign in gather], axis=1)
        np.testing.assert_array_equal(got, X @ M)


def test_the_constant_joints_are_zero_and_every_joint_is_written(truth):
    """The joints' arrays are not cleared first (np.empty): the constant joints' columns (half track, half
    wheelbase: their value is in the MDH r column) are zeroed, every other column written by a stage."""
    from dynid.vehicle.template import CONSTANT_JOINTS

    model, *_, channels = truth
    est = estimate_joints(si(channels), FS, model)
    for a in (est.q, est.qd, est.qdd):
        assert np.isfinite(a).all()
        assert not a[:, [j - 1 for j in CONSTANT_JOINTS]].any()


@pytest.mark.parametrize("channel", ["imu_yaw_rate", "wft_fl_Fz", "laser_height_rr", "correvit_vy"])
def test_a_non_finite_channel_is_named_with_its_sample(truth, channel):
    """The pass checks the channels it reads once, up front, and its filters skip their own scans: a NaN or an
    infinity in any of them is an error naming that channel and its first bad sample (before, a column of a matrix
    computed from the channels, or none for the rates integrated before the first filter)."""
    from dynid.model import ModelError

    model, *_, channels = truth
    ch = si(channels)
    x = ch[channel].copy()
    x[[1234, 2000]] = [np.nan, np.inf]
    ch[channel] = x
    with pytest.raises(ModelError, match=rf"channel '{channel}' has a non-finite value \(nan\) at sample 1234 \(2 in"):
        estimate_joints(ch, FS, model)


@pytest.mark.parametrize("where", ["none", "low", "high", "both"])
def test_the_saturated_cameras_are_found_from_their_extremes(where):
    """`_saturated_cameras` tests a channel's least and largest sample first and scans it only when one reaches a
    limit; oracle: the limit test of every sample (the sensor's `saturated` on the values as logged, widened by a
    hundredth of the resolution), on channels whose extremes sit exactly on a limit, just inside it, or both."""
    from dynid.vehicle.estimate import _saturated_cameras
    from dynid.vehicle.sensors import CORNER_TAGS, paper_suite

    suite = paper_suite()
    rng = np.random.default_rng(12)
    ch = {}
    for t in CORNER_TAGS:
        for prefix in ("steer", "camber"):
            name = f"{prefix}_{t}"
            c = suite[name]
            lo, hi = c.range
            x = rng.uniform(0.5 * lo, 0.5 * hi, 2000)
            # exactly on the limit (a clipped sample), or a resolution inside it
            x[17] = lo if where in ("low", "both") else lo + c.resolution
            x[1900] = hi if where in ("high", "both") else hi - c.resolution
            ch[name] = np.radians(x) if c.unit == "deg" else x
    got = _saturated_cameras(ch, suite)
    for name, x in ch.items():
        c = suite[name]
        scale = np.pi / 180.0 if c.unit == "deg" else 1.0
        tol = 0.01 * c.resolution
        ref = c.saturated(x / scale + np.where(x > 0, tol, -tol))
        if ref.any():
            np.testing.assert_array_equal(got[name], ref)
        else:
            assert name not in got
    assert (len(got) == 0) == (where == "none")
