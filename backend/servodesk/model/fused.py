"""One move of a noiseless simulated axis with the servo loop and the plant fused into one
tick loop: what model/replay.py's ``run_move`` computes, several times faster.

The tuning ranks its candidates by running each through the reference move on the identified
axis (``ModelMoves``), and the benchmark's oracle runs hundreds more on the true plant: these
tick loops are where a tuning spends its compute (a 16 kHz loop watched for a second is 16 000
ticks per candidate). Through ``ServoLoop.update`` and ``Plant.step`` each tick costs six
method calls and their attribute traffic; here the loop's and the plant's state live in locals.

The arithmetic is theirs, operation for operation, so the result is the same to the last bit
(tests/sim/test_fused_move.py runs both paths on rigid and two-mass axes with friction that
sticks, gravity, filters and the torque clamp and requires equal arrays). A change to
``ServoLoop.update``/``_velocity_loop``/``_output``, ``Plant.step`` or a mechanics'
``advance`` must be made here too; that test fails until it is. The coefficients are read from
a ``ServoLoop`` and a ``Plant`` built as usual (same package, so their private fields are read
directly), never recomputed here.

The tick loop itself (:func:`_ticks`) is compiled by numba (nopython, no fast-math: IEEE
double arithmetic in the order written, no fused multiply-adds, so the compiled loop gives the
Python loop's positions to the bit, and tests/sim/test_fused_move.py checks both against the
per-method path). Compiled, a tick costs 0.02-0.04 µs, under a twentieth of the Python loop
(bench/bench_replay.py). numba is imported and the loop compiled on first use
(:func:`compiled_ticks`), and the machine code is cached beside the module (or in numba's user
cache where that is read-only), so a new process loads it instead of compiling it again
(about a second).

Not for a plant with torque or encoder noise or a dead time (:func:`fused_move` returns
None and the caller takes the per-method path).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from servodesk.domain.tuning.gains import ServoGains
from servodesk.model.plant import (
    Plant,
    PlantParams,
    RigidMechanics,
    TwoMassMechanics,
    mechanics_for,
)
from servodesk.model.servo import ServoLoop

FloatArray = npt.NDArray[np.float64]


def applies(params: PlantParams) -> bool:
    """Whether :func:`fused_move` can run ``params`` (no noise, no dead time)."""
    return not (params.torque_noise or params.noise_counts or params.dead_time > 0.0)


def fused_move(
    params: PlantParams,
    gains: ServoGains,
    rate_hz: float,
    torque_limit: float,
    p: Sequence[float] | FloatArray,
    v: Sequence[float] | FloatArray,
    a: Sequence[float] | FloatArray,
    hold_ticks: int = 0,
) -> FloatArray | None:
    """The motor position per tick [counts] for the demands ``p`` [rad], ``v`` [rad/s], ``a``
    [rad/s²] under ``gains``, after ``hold_ticks`` ticks of holding at 0; NaN from the tick
    the loop's torque stops being finite. None when the plant is not one this path runs
    (:func:`applies`)."""
    if not applies(params):
        return None
    plant = Plant(params, mechanics_for(params))
    loop = ServoLoop(gains, rate_hz, params.counts_per_rev, torque_limit)
    return fused_ticks(plant, loop, rate_hz, p, v, a, hold_ticks)


def fused_ticks(
    plant: Plant,
    loop: ServoLoop,
    rate_hz: float,
    p: Sequence[float] | FloatArray,
    v: Sequence[float] | FloatArray,
    a: Sequence[float] | FloatArray,
    hold_ticks: int = 0,
) -> FloatArray:
    """:func:`fused_move` from the state ``plant`` and ``loop`` are in (a replay starts where a
    recording found the axis: replay.run_recorded_move), leaving both as they were: the encoder
    reading at the start of each tick [counts]. The plant must be one :func:`applies` to (its
    parameters); ``p`` [rad] is each tick's demand as the loop compares it with the encoder."""
    mech = plant.mechanics
    dt = 1.0 / rate_hz
    plant._set_dt(dt)
    # Every coefficient as a Python float: an identified model's inertias and friction and a
    # designed gain set's fields are often numpy scalars, whose arithmetic is the same IEEE
    # double arithmetic at several times the cost per operation.
    alpha = float(plant._alpha)
    beta = float(plant._beta)
    peak = float(plant._peak)
    scale = float(plant._scale)

    # The servo loop (ServoLoop.update, _velocity_loop, _output).
    rad = float(loop._rad)
    rr = float(loop._rr)
    kp = float(loop._kp)
    kv = float(loop._kv)
    ki = float(loop._ki)
    kvff = float(loop._kvff)
    jff = float(loop._jff)
    tt = float(loop.tau_test)
    lim = float(loop.torque_limit)
    lp_on = loop._lp_on
    lb0, lb1, _lb2, la1, _la2 = map(float, loop._lp)
    n1_on = loop._n1_on
    p10, p11, p12, q11, q12 = map(float, loop._n1)
    n2_on = loop._n2_on
    p20, p21, p22, q21, q22 = map(float, loop._n2)
    lz = float(loop._lp_z)
    z11 = float(loop._n1_z1)
    z12 = float(loop._n1_z2)
    z21 = float(loop._n2_z1)
    z22 = float(loop._n2_z2)
    prev = loop._prev
    integ = float(loop.integral)
    s = loop.saturated
    nxt = float(loop._next)
    torque_state = float(plant.torque)

    # The mechanics' coefficients and state: a two-mass axis (TwoMassMechanics.advance) or a
    # rigid one (RigidMechanics.advance); the other's stay unused. One branch per tick costs
    # far less than the loop's arithmetic.
    two_mass = isinstance(mech, TwoMassMechanics)
    move_c = [0.0] * 20
    lock_c = [0.0] * 6
    stiff = damper = fc = g = lp_ = wl = 0.0
    inv_j = visc = c = grav = 0.0
    exact = False
    if isinstance(mech, TwoMassMechanics):
        mech._discretise(dt)
        move_c = [float(x) for x in mech._move]
        lock_c = [float(x) for x in mech._lock]
        stiff = float(mech.stiffness)
        damper = float(mech.damper)
        fc = float(mech.coulomb)
        g = float(mech.gravity)
        lp_ = float(mech.load_pos)
        wl = float(mech.load_vel)
    else:
        assert isinstance(mech, RigidMechanics)
        inv_j = float(mech.inv_inertia)
        visc = float(mech.viscous)
        c = float(mech.coulomb)
        grav = float(mech.gravity)
        exact = mech.exact
    # Every coefficient and state in one array (the order _ticks reads them in) and the
    # switches in another: the compiled loop takes arrays, not sixty arguments.
    coef = [
        alpha, beta, peak, scale, dt,
        rad, rr, kp, kv, ki, kvff, jff, tt, lim,
        lb0, lb1, la1, p10, p11, p12, q11, q12, p20, p21, p22, q21, q22,
        lz, z11, z12, z21, z22, float(prev), integ, nxt, torque_state,
        *move_c, *lock_c,
        stiff, damper, fc, g, lp_, wl, inv_j, visc, c, grav,
        float(mech.position), float(mech.velocity),
    ]  # fmt: skip
    flags = [int(lp_on), int(n1_on), int(n2_on), int(s), int(two_mass), int(exact)]
    if COMPILED:
        return compiled_ticks()(  # type: ignore[no-any-return]
            np.array(coef, dtype=np.float64),
            np.array(flags, dtype=np.int64),
            np.asarray(p, dtype=np.float64),
            np.asarray(v, dtype=np.float64),
            np.asarray(a, dtype=np.float64),
            hold_ticks,
        )

    # As Python: lists of Python floats (numpy scalars cost several times more per operation).
    def floats(x: Sequence[float] | FloatArray) -> list[float]:
        return np.asarray(x, dtype=np.float64).tolist()  # type: ignore[no-any-return]

    return _ticks(coef, flags, floats(p), floats(v), floats(a), hold_ticks)


def _ticks(
    coef: Sequence[float],
    flags: Sequence[int],
    p: Sequence[float],
    v: Sequence[float],
    a: Sequence[float],
    hold_ticks: int,
) -> FloatArray:
    """The tick loop of :func:`fused_move` over the coefficients and states it packed: the
    same source runs compiled (numba, :func:`compiled_ticks`) and as Python (lists of floats)."""
    # Unpacked by index: numba does not unpack an array.
    alpha = coef[0]
    beta = coef[1]
    peak = coef[2]
    scale = coef[3]
    dt = coef[4]
    rad = coef[5]
    rr = coef[6]
    kp = coef[7]
    kv = coef[8]
    ki = coef[9]
    kvff = coef[10]
    jff = coef[11]
    tt = coef[12]
    lim = coef[13]
    lb0 = coef[14]
    lb1 = coef[15]
    la1 = coef[16]
    p10 = coef[17]
    p11 = coef[18]
    p12 = coef[19]
    q11 = coef[20]
    q12 = coef[21]
    p20 = coef[22]
    p21 = coef[23]
    p22 = coef[24]
    q21 = coef[25]
    q22 = coef[26]
    lz = coef[27]
    z11 = coef[28]
    z12 = coef[29]
    z21 = coef[30]
    z22 = coef[31]
    prev = coef[32]
    integ = coef[33]
    nxt = coef[34]
    torque_state = coef[35]
    q0 = coef[36]
    q1_ = coef[37]
    q2 = coef[38]
    q3 = coef[39]
    q4 = coef[40]
    m0 = coef[41]
    m1 = coef[42]
    m2 = coef[43]
    m3 = coef[44]
    m4 = coef[45]
    l0 = coef[46]
    l1 = coef[47]
    l2 = coef[48]
    l3 = coef[49]
    l4 = coef[50]
    c0 = coef[51]
    c1 = coef[52]
    c2 = coef[53]
    c3 = coef[54]
    c4 = coef[55]
    a00 = coef[56]
    a01 = coef[57]
    a02 = coef[58]
    a10 = coef[59]
    a11 = coef[60]
    a12 = coef[61]
    stiff = coef[62]
    damper = coef[63]
    fc = coef[64]
    g = coef[65]
    lp_ = coef[66]
    wl = coef[67]
    inv_j = coef[68]
    visc = coef[69]
    c = coef[70]
    grav = coef[71]
    pm = coef[72]
    wm = coef[73]
    lp_on = flags[0]
    n1_on = flags[1]
    n2_on = flags[2]
    s = flags[3]
    two_mass = flags[4]
    exact = flags[5]
    n = len(p)
    pos = np.empty(n)
    total = hold_ticks + n

    for t in range(total):
        enc = math.floor(pm * scale)
        if t < hold_ticks:
            pd = vd = ad = 0.0
        else:
            k = t - hold_ticks
            pos[k] = enc
            pd = p[k]
            vd = v[k]
            ad = a[k]
        # ServoLoop.update, _velocity_loop, _output
        vmeas = (enc - prev) * rr
        prev = enc
        ev = kp * (pd - enc * rad) + kvff * vd - vmeas
        if ki and not ((s > 0 and ev > 0.0) or (s < 0 and ev < 0.0)):
            integ += ki * ev
        x = kv * ev + integ + jff * ad + tt
        if lp_on:
            y = lb0 * x + lz
            lz = lb1 * x - la1 * y
            x = y
        if n1_on:
            y = p10 * x + z11
            z11 = p11 * x - q11 * y + z12
            z12 = p12 * x - q12 * y
            x = y
        if n2_on:
            y = p20 * x + z21
            z21 = p21 * x - q21 * y + z22
            z22 = p22 * x - q22 * y
            x = y
        if x > lim:
            x = lim
            s = 1
        elif x < -lim:
            x = -lim
            s = -1
        else:
            s = 0
        cmd = nxt
        nxt = x
        if t >= hold_ticks and not math.isfinite(cmd):
            pos[t - hold_ticks :] = math.nan
            break
        # Plant.step
        if cmd > peak:
            cmd = peak
        elif cmd < -peak:
            cmd = -peak
        t0 = torque_state
        torque_state = t0 + (cmd - t0) * alpha
        tq = cmd + (t0 - cmd) * beta
        if two_mass:
            # TwoMassMechanics.advance
            q = pm - lp_
            if wl == 0.0 and fc > 0.0:
                drive = stiff * q + damper * wm - g
                if -fc <= drive <= fc:
                    q1 = a00 * q + a01 * wm + a02 * tq
                    wm = a10 * q + a11 * wm + a12 * tq
                    pm = pm + q1 - q
                    continue
                f = -g - (fc if drive > 0.0 else -fc)
            else:
                f = -g - (fc if wl > 0.0 else -fc if wl < 0.0 else 0.0)
            q_new = q0 * q + q1_ * wm + q2 * wl + q3 * tq + q4 * f
            wm_new = m0 * q + m1 * wm + m2 * wl + m3 * tq + m4 * f
            wl_new = l0 * q + l1 * wm + l2 * wl + l3 * tq + l4 * f
            pm_new = pm + c0 * q + c1 * wm + c2 * wl + c3 * tq + c4 * f
            if wl != 0.0 and (wl > 0.0) != (wl_new > 0.0):
                drive = stiff * q_new + damper * wm_new - g
                if -fc <= drive <= fc:
                    wl_new = 0.0
            pm = pm_new
            wm = wm_new
            lp_ = pm_new - q_new
            wl = wl_new
        else:
            # RigidMechanics.advance
            drive = tq - grav
            if wm == 0.0:
                if -c <= drive <= c:
                    continue
                net = drive - c if drive > 0.0 else drive + c
                w_new = net * inv_j * dt
            else:
                net = drive - visc * wm - (c if wm > 0.0 else -c)
                w_new = wm + net * inv_j * dt
                if (wm > 0.0) != (w_new > 0.0) and -c <= drive <= c:
                    w_new = 0.0
            if exact:
                pm += 0.5 * (wm + w_new) * dt
            else:
                pm += w_new * dt
            wm = w_new
    return pos


#: Run the tick loop compiled (numba); False runs it as Python (tests and bench/bench_replay.py
#: compare the two).
COMPILED = True
_compiled: Any = None


def compiled_ticks() -> Any:
    """:func:`_ticks` compiled, on first use: numba is imported only then (1.2 s, which a
    server or CLI start that never ranks gains need not pay), and the machine code is cached
    for the next process where a cache directory is writable (else compiled anew, about a
    second)."""
    global _compiled
    if _compiled is None:
        import numba

        try:
            _compiled = numba.njit(cache=True, nogil=True)(_ticks)
        except RuntimeError:  # No writable cache directory (a read-only install).
            _compiled = numba.njit(nogil=True)(_ticks)
    return _compiled
