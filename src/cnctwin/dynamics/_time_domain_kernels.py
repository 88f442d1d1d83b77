"""Numba kernel of the time-domain milling simulation (see :mod:`cnctwin.dynamics.time_domain`).

Arrays in SI units. The cutter's edge points live on a fixed grid of spatial immersion angles:
slice ``s`` (helix lag ``psi_s``) has ``N m`` angles ``phi = k dtheta - psi_s`` (tables are
indexed ``[k, s]``),
``dtheta = 2 pi / (N m)``, and tooth ``j`` sits on grid angle ``k = (i + j m) mod (N m)`` at
step ``i`` (``m`` steps per tooth period). Each angle is visited once per tooth period, by the
next tooth. ``surface[k, s]`` holds the position, projected on the angle's radial direction
``u = (sin phi, cos phi)``, where the last tooth that cut there left the material; the chip a
tooth meets is ``h = p - surface`` with ``p = f_z sin(phi) i / m + u . r`` (the feed advanced
so far plus the tool-tip displacement ``r``). When all teeth cut, this is Royandi 2026, Eq. 12,
``h = f_z sin(phi) + u . (r(t) - r(t - T))``; a tooth with ``h <= 0`` has left the cut, feels no
force and leaves the surface as it was (Tlusty's memory of the surface).

The kernels touch arrays and numbers only, no Python object: compiled ``nogil``, they run
without the GIL, so the virtual machine's stepping thread (:class:`~cnctwin.virtual.
SteppedOffLoop`) integrates its vibration while its server's thread answers requests.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def cutting_force(
    step: int,
    advance: float,
    ry: float,
    steps_per_tooth: int,
    feed: float,
    inside: np.ndarray,
    sin_t: np.ndarray,
    cos_t: np.ndarray,
    cut_x: np.ndarray,
    cut_y: np.ndarray,
    edge_x: np.ndarray,
    edge_y: np.ndarray,
    surface: np.ndarray,
    regenerative: bool,
    update: bool,
) -> tuple[float, float]:  # pragma: no cover - compiled
    """Cutting force on the tool (N) at step ``step``: ``advance`` is the feed advanced so far
    plus the tip's x displacement, ``ry`` its y displacement, m.

    ``inside`` marks the grid angles inside the immersion; ``cut_x``, ``cut_y`` (N per m of
    chip) and ``edge_x``, ``edge_y`` (N) are the force of each grid angle per unit chip
    thickness and its edge part; ``update`` writes the new surface where a tooth cut.
    """
    grid, slices = sin_t.shape
    teeth = grid // steps_per_tooth
    fx = 0.0
    fy = 0.0
    for j in range(teeth):
        k = (step + j * steps_per_tooth) % grid
        for s in range(slices):
            if not inside[k, s]:
                continue
            if regenerative:
                p = sin_t[k, s] * advance + cos_t[k, s] * ry
                h = p - surface[k, s]
                if h <= 0.0:
                    continue
                if update:
                    surface[k, s] = p
            else:
                h = feed * sin_t[k, s]
                if h <= 0.0:
                    continue
            fx += cut_x[k, s] * h + edge_x[k, s]
            fy += cut_y[k, s] * h + edge_y[k, s]
    return fx, fy


@njit(cache=True, nogil=True)
def simulate(
    transition: np.ndarray,
    hold: np.ndarray,
    ramp: np.ndarray,
    tip: np.ndarray,
    accel_state: np.ndarray,
    accel_force: np.ndarray,
    state: np.ndarray,
    steps_per_tooth: int,
    feed: float,
    inside: np.ndarray,
    sin_t: np.ndarray,
    cos_t: np.ndarray,
    cut_x: np.ndarray,
    cut_y: np.ndarray,
    edge_x: np.ndarray,
    edge_y: np.ndarray,
    surface: np.ndarray,
    regenerative: bool,
    out: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """March ``out.shape[0]`` steps from ``state`` (modal displacements, then velocities) at
    step 0 with no feed advanced: the force there, then :func:`march`."""
    n = tip.shape[1]
    rx = 0.0
    ry = 0.0
    for q in range(n):
        rx += tip[0, q] * state[q]
        ry += tip[1, q] * state[q]
    force = np.empty(2)
    force[0], force[1] = cutting_force(0, rx, ry, steps_per_tooth, feed, inside, sin_t, cos_t,
                                       cut_x, cut_y, edge_x, edge_y, surface, regenerative,
                                       True)  # fmt: skip
    march(transition, hold, ramp, tip, accel_state, accel_force, state.copy(), force, 0, 0.0,
          steps_per_tooth, feed, inside, sin_t, cos_t, cut_x, cut_y, edge_x, edge_y, surface,
          regenerative, out)  # fmt: skip


@njit(cache=True, nogil=True)
def march(
    transition: np.ndarray,
    hold: np.ndarray,
    ramp: np.ndarray,
    tip: np.ndarray,
    accel_state: np.ndarray,
    accel_force: np.ndarray,
    state: np.ndarray,
    force: np.ndarray,
    start: int,
    base: float,
    steps_per_tooth: int,
    feed: float,
    inside: np.ndarray,
    sin_t: np.ndarray,
    cos_t: np.ndarray,
    cut_x: np.ndarray,
    cut_y: np.ndarray,
    edge_x: np.ndarray,
    edge_y: np.ndarray,
    surface: np.ndarray,
    regenerative: bool,
    out: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """March ``out.shape[0]`` steps from step ``start``, in place.

    ``state`` (modal displacements, then velocities) and ``force`` (x, y, N; the cutting force
    of that state, the surface already updated with it) are those at step ``start``, where the
    feed has advanced ``base`` m; on return they are those at step ``start + out.shape[0]``,
    so that a stream of calls continues one simulation (the virtual machine's vibration,
    :mod:`cnctwin.virtual.vibration`).

    One step of length ``dt`` is exact for the linear modal dynamics with a force varying
    linearly over the step (first-order hold): ``x+ = transition x + hold F_i +
    ramp (F_(i+1) - F_i)``. ``F_(i+1)`` depends on ``x+`` through the chip, so it is predicted
    from the zero-order-hold step first and the step is then taken with the predicted force
    (Heun's predictor-corrector; second order in dt). ``tip`` (2, n) maps modal to tip
    displacement; ``accel_state`` (2, 2n) and ``accel_force`` (2, 2) give the tip acceleration.

    ``out`` (steps, 8) receives per step: displacement x, y (m), velocity x, y (m/s),
    acceleration x, y (m/s^2) and cutting force x, y (N) on the tool.
    """
    n = tip.shape[1]
    size = 2 * n
    x = state
    base_state = np.empty(size)
    trial = np.empty(size)
    fx = force[0]
    fy = force[1]
    rx = 0.0
    ry = 0.0
    for q in range(n):
        rx += tip[0, q] * x[q]
        ry += tip[1, q] * x[q]
    total = out.shape[0]
    for i in range(total):
        vx = 0.0
        vy = 0.0
        for q in range(n):
            vx += tip[0, q] * x[n + q]
            vy += tip[1, q] * x[n + q]
        ax = accel_force[0, 0] * fx + accel_force[0, 1] * fy
        ay = accel_force[1, 0] * fx + accel_force[1, 1] * fy
        for q in range(size):
            ax += accel_state[0, q] * x[q]
            ay += accel_state[1, q] * x[q]
        out[i, 0] = rx
        out[i, 1] = ry
        out[i, 2] = vx
        out[i, 3] = vy
        out[i, 4] = ax
        out[i, 5] = ay
        out[i, 6] = fx
        out[i, 7] = fy
        for p in range(size):
            acc = hold[p, 0] * fx + hold[p, 1] * fy
            for q in range(size):
                acc += transition[p, q] * x[q]
            base_state[p] = acc
        px = 0.0
        py = 0.0
        for q in range(n):
            px += tip[0, q] * base_state[q]
            py += tip[1, q] * base_state[q]
        step = start + i + 1
        fed = base + feed * (i + 1) / steps_per_tooth
        gx, gy = cutting_force(step, fed + px, py, steps_per_tooth, feed, inside, sin_t, cos_t,
                               cut_x, cut_y, edge_x, edge_y, surface, regenerative,
                               False)  # fmt: skip
        dx = gx - fx
        dy = gy - fy
        for p in range(size):
            trial[p] = base_state[p] + ramp[p, 0] * dx + ramp[p, 1] * dy
        x[:] = trial
        rx = 0.0
        ry = 0.0
        for q in range(n):
            rx += tip[0, q] * x[q]
            ry += tip[1, q] * x[q]
        fx, fy = cutting_force(step, fed + rx, ry, steps_per_tooth, feed, inside, sin_t, cos_t,
                               cut_x, cut_y, edge_x, edge_y, surface, regenerative,
                               True)  # fmt: skip
    force[0] = fx
    force[1] = fy
