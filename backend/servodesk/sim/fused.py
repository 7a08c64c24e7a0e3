"""One move of a noiseless simulated axis with the servo loop and the plant fused into one
tick loop: what sim/replay.py's ``run_move`` computes, several times faster.

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

Not for a plant with torque or encoder noise or a dead time (:func:`fused_move` returns
None and the caller takes the per-method path).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from servodesk.domain.tuning.gains import ServoGains
from servodesk.sim.plant import Plant, PlantParams, RigidMechanics, TwoMassMechanics, mechanics_for
from servodesk.sim.servo import ServoLoop

FloatArray = npt.NDArray[np.float64]


def applies(params: PlantParams) -> bool:
    """Whether :func:`fused_move` can run ``params`` (no noise, no dead time)."""
    return not (params.torque_noise or params.noise_counts or params.dead_time > 0.0)


def fused_move(
    params: PlantParams,
    gains: ServoGains,
    rate_hz: float,
    torque_limit: float,
    p: list[float],
    v: list[float],
    a: list[float],
    hold_ticks: int = 0,
) -> FloatArray | None:
    """The motor position per tick [counts] for the demands ``p`` [rad], ``v`` [rad/s], ``a``
    [rad/s²] under ``gains``, after ``hold_ticks`` ticks of holding at 0; NaN from the tick
    the loop's torque stops being finite. None when the plant is not one this path runs
    (:func:`applies`)."""
    if not applies(params):
        return None
    mech = mechanics_for(params)
    plant = Plant(params, mech)
    loop = ServoLoop(gains, rate_hz, params.counts_per_rev, torque_limit)
    dt = 1.0 / rate_hz
    plant._set_dt(dt)
    # Every coefficient as a Python float: an identified model's inertias and friction and a
    # designed gain set's fields are often numpy scalars, whose arithmetic is the same IEEE
    # double arithmetic at several times the cost per operation.
    alpha = float(plant._alpha)
    beta = float(plant._beta)
    peak = float(plant._peak)
    scale = float(plant._scale)
    floor = math.floor
    isfinite = math.isfinite

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

    n = len(p)
    pos = np.empty(n)
    total = hold_ticks + n

    # The mechanics' coefficients and state: a two-mass axis (TwoMassMechanics.advance) or a
    # rigid one (RigidMechanics.advance); the other's stay unused. One branch per tick costs
    # far less than the loop's arithmetic.
    two_mass = isinstance(mech, TwoMassMechanics)
    q0 = q1_ = q2 = q3 = q4 = m0 = m1 = m2 = m3 = m4 = 0.0
    l0 = l1 = l2 = l3 = l4 = c0 = c1 = c2 = c3 = c4 = 0.0
    a00 = a01 = a02 = a10 = a11 = a12 = 0.0
    stiff = damper = fc = g = lp_ = wl = 0.0
    inv_j = visc = c = grav = 0.0
    exact = False
    if isinstance(mech, TwoMassMechanics):
        mech._discretise(dt)
        (
            q0, q1_, q2, q3, q4,
            m0, m1, m2, m3, m4,
            l0, l1, l2, l3, l4,
            c0, c1, c2, c3, c4,
        ) = map(float, mech._move)  # fmt: skip
        a00, a01, a02, a10, a11, a12 = map(float, mech._lock)
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
    pm = float(mech.position)
    wm = float(mech.velocity)

    for t in range(total):
        enc = floor(pm * scale)
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
        if t >= hold_ticks and not isfinite(cmd):
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
