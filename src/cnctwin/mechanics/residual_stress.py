"""Elastic machining-induced residual stress (MIRS) of Ward et al. 2021 (Sec. 3.3, Eq. 3-5).

Ward 2021 predicts an *elastic* MIRS depth profile from the mechanical (and thermal) load of
the cut and a release of the loaded state to the residual boundary conditions. The paper gives
the release (Eq. 3-5) but not the loading model; the loading here is that of the analytical
MIRS models Ward builds on (Liang & Su 2007, CIRP Annals 56(1); Ulutan, Erdem Alaca & Lazoglu
2007, J. Mater. Process. Technol. 183), which take the loaded state from the elastic field of the
cutting edge's contact load on the new surface:

1. **Surface load.** A normal load ``P`` and a tangential load ``Q`` per unit width (N/m) act
   on the machined surface over a contact of length ``2a`` with a Hertzian distribution
   (``p(s) = p0 sqrt(1 - s^2/a^2)``, ``p0 = 2P / (pi a)``); the tangential traction has the
   same shape. (The loading field also takes a uniform load, ``P / 2a``, whose closed form
   checks it; its tangential part is singular at the contact's edges, so the MIRS model does
   not take it.)
2. **Loading stresses** in the half-space ``z >= 0`` (plane strain; ``x`` along the feed,
   ``y`` along the edge, ``z`` into the part): the superposition of Flamant's line-load field
   (Johnson 1985, *Contact Mechanics*, Eq. 2.15 normal, 2.19 tangential, 2.23 distributed)::

       sigma_xx = -(2/pi) Int [p(s) z u^2 + q(s) u^3] / r^4 ds
       sigma_zz = -(2/pi) Int [p(s) z^3   + q(s) u z^2] / r^4 ds
       tau_xz   = -(2/pi) Int [p(s) u z^2 + q(s) u^2 z] / r^4 ds,    u = x - s, r^2 = u^2 + z^2

   with ``sigma_yy = nu (sigma_xx + sigma_zz)`` (plane strain). The integrals are exact for a
   load that is linear between nodes (closed-form antiderivatives; the Hertzian shape is
   sampled at ``segments + 1`` nodes, scaled to carry exactly ``P`` and ``Q``), so the field is
   finite and accurate up to the surface. An optional temperature rise ``T(z)`` (K) of a
   laterally uniform layer adds ``sigma_xx = sigma_yy = -E alpha T / (1 - nu)`` (the layer held
   by the bulk in x and y; Timoshenko & Goodier, *Theory of Elasticity*, Sec. 151).
3. **Loaded state per depth.** At each depth the loaded state is the one of the load cycle
   with the largest von Mises stress (the position along ``x`` where the passing load strains
   that depth most; where plasticity would start first).
4. **Release (Ward Eq. 3-5).** The residual state satisfies ``sigma_zz^r = tau_xz^r = 0`` and
   ``eps_xx^r = eps_yy^r = 0`` (Eq. 3; the layer stays bonded to the bulk). ``sigma_zz`` and
   ``T`` are relaxed in ``M`` increments ``Delta sigma_zz = -sigma_zz / M``,
   ``Delta T = -T / M`` with ``Delta eps_xx = -eps_xx^r / M = 0`` (Eq. 4), each giving (Eq. 5,
   which is Hooke's law with ``Delta eps_yy = 0``)::

       d_sigma_xx = [E d_eps_xx + (1 + nu)(nu d_sigma_zz - E alpha d_T)] / (1 - nu^2)
       d_sigma_yy = [nu E d_eps_xx + (1 + nu)(nu d_sigma_zz - E alpha d_T)] / (1 - nu^2)

   The increments are linear with constant coefficients, so the ``M`` steps sum exactly to::

       sigma_xx^r = sigma_xx - (nu sigma_zz - E alpha T) / (1 - nu)
       sigma_yy^r = sigma_yy - (nu sigma_zz - E alpha T) / (1 - nu)

   (``tau_xz`` relaxes on its own: shear does not couple to normal stress in isotropic
   elasticity). A laterally uniform temperature therefore leaves no elastic residual stress;
   the thermal load changes the result only through the choice of the loaded state (3).

What this is and is not: it is the in-plane stress the layer would keep if it kept the
in-plane strain it had under the load. It is linear in the load for a fixed contact and
distribution, has no plasticity (Ward: "only elastic MIRS were calculated") and no cutting-speed
effect of its own. The paper's reading of Eq. 4 with ``Delta eps_xx = -eps_xx / M`` for the
loaded strain would cancel every elastic stress exactly (the release of a purely elastic state
is zero); ``eps_xx^r = 0`` of Eq. 3 is taken literally instead. docs/residual_stress.md
compares the result with Ward's numbers.

SI units throughout: m, N/m, Pa, K, 1/K.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from cnctwin.errors import ConfigError
from cnctwin.mechanics import _residual_stress_kernels as _kernels
from cnctwin.mechanics.coefficients import CuttingCoefficients
from cnctwin.mechanics.materials import ElasticMaterial

__all__ = [
    "ElasticMirsModel",
    "LoadingStresses",
    "ResidualStressProfile",
    "SurfaceLoad",
    "edge_surface_load",
    "elastic_mirs",
    "elastic_release",
    "loading_stresses",
    "milling_surface_load",
]

Distribution = Literal["hertzian", "uniform"]

#: Segments of the piecewise-linear Hertzian load (cosine spacing, dense at the contact's
#: ends) and positions along x scanned for each depth's loaded state. With 96 and 321 the
#: largest |sigma_xx| is within 0.3 % of a 256-segment, 1281-position solution for a 0.1 mm and
#: a 3.4 mm contact (docs/residual_stress.md, "Accuracy").
DEFAULT_SEGMENTS = 96
DEFAULT_POSITIONS = 321
#: Squared distance below which a point is on a load node (m^2): log(r) is taken there, and
#: the terms of two adjoining segments cancel.
_TINY_R2 = 1e-300


@dataclass(frozen=True)
class SurfaceLoad:
    """The cutting edge's contact load on the machined surface, per unit width of edge.

    Attributes
    ----------
    normal_n_m
        Normal load P pressing on the surface, N/m (>= 0).
    tangential_n_m
        Tangential load Q along +x (the direction the edge drags the surface), N/m.
    contact_length_m
        Contact length 2a along x, m (> 0).
    distribution
        ``"hertzian"`` (elliptical, zero at the contact's ends) or ``"uniform"``.
    """

    normal_n_m: float
    tangential_n_m: float
    contact_length_m: float
    distribution: Distribution = "hertzian"

    def __post_init__(self) -> None:
        checks = (
            ("normal_n_m", self.normal_n_m, self.normal_n_m >= 0.0, "a finite value >= 0 N/m"),
            ("tangential_n_m", self.tangential_n_m, True, "a finite value in N/m"),
            (
                "contact_length_m",
                self.contact_length_m,
                0.0 < self.contact_length_m <= 0.1,
                "0 < contact_length_m <= 0.1 m",
            ),
        )
        for name, value, ok, valid in checks:
            if not (math.isfinite(value) and ok):
                raise ConfigError(f"SurfaceLoad {name} = {value!r}; give {valid}")
        if self.distribution not in ("hertzian", "uniform"):
            raise ConfigError(
                f"SurfaceLoad distribution = {self.distribution!r}; give 'hertzian' or 'uniform'"
            )

    @property
    def half_length_m(self) -> float:
        """Half the contact length a, m."""
        return 0.5 * self.contact_length_m


@dataclass(frozen=True)
class LoadingStresses:
    """The elastic loading field of a surface load on a grid (plane strain, Pa).

    Arrays have shape ``(len(x_m), len(z_m))``.

    Attributes
    ----------
    x_m, z_m
        Positions along the feed relative to the contact centre and depths below the
        surface, m.
    sigma_xx, sigma_zz, tau_xz
        Stress components, Pa (tension positive).
    """

    x_m: NDArray[np.float64]
    z_m: NDArray[np.float64]
    sigma_xx: NDArray[np.float64]
    sigma_zz: NDArray[np.float64]
    tau_xz: NDArray[np.float64]


@dataclass(frozen=True)
class ResidualStressProfile:
    """An elastic MIRS depth profile (Ward 2021, Eq. 3-5).

    Attributes
    ----------
    depth_m
        Depths below the machined surface, m.
    sigma_xx_pa, sigma_yy_pa
        Residual stress along the feed (longitudinal, Ward's sigma_xx) and along the edge, Pa.
    loaded_x_m
        Position along x of the loaded state taken at each depth, m.
    loaded_von_mises_pa
        Von Mises stress of that loaded state, Pa.
    """

    depth_m: NDArray[np.float64]
    sigma_xx_pa: NDArray[np.float64]
    sigma_yy_pa: NDArray[np.float64]
    loaded_x_m: NDArray[np.float64]
    loaded_von_mises_pa: NDArray[np.float64]

    @property
    def max_abs_xx_pa(self) -> float:
        """The largest magnitude of sigma_xx over depth, Pa (Ward's "maximum elastic MIRS")."""
        return float(np.max(np.abs(self.sigma_xx_pa)))


def edge_surface_load(
    coefficients: CuttingCoefficients,
    chip_thickness_m: float,
    contact_length_m: float,
) -> SurfaceLoad:
    """The edge load per unit width at a chip thickness (Ward 2021, Eq. 1 with b = 1).

    Ward's element force per unit chip width: ``F_t = Ktc h + Kte`` (tangential) drags the
    surface (Q), ``F_r = Krc h + Kre`` (radial) presses on it (P, taken as its magnitude).

    Parameters
    ----------
    coefficients
        Cutting (Pa) and edge (N/m) coefficients.
    chip_thickness_m
        Uncut chip thickness h, m (>= 0).
    contact_length_m
        Contact length of the edge on the surface 2a, m.

    Returns
    -------
    SurfaceLoad
        P and Q in N/m, Hertzian.
    """
    if not (math.isfinite(chip_thickness_m) and 0.0 <= chip_thickness_m <= 0.01):
        raise ConfigError(f"chip thickness = {chip_thickness_m!r} m; give 0 <= h <= 0.01 m (10 mm)")
    k, h = coefficients, chip_thickness_m
    return SurfaceLoad(
        normal_n_m=abs(k.krc * h + k.kre),
        tangential_n_m=k.ktc * h + k.kte,
        contact_length_m=contact_length_m,
    )


def milling_surface_load(
    coefficients: CuttingCoefficients,
    feed_per_tooth_m: float,
    entry_rad: float,
    exit_rad: float,
    contact_length_m: float,
) -> SurfaceLoad:
    """The largest edge load per unit width of a milling cut (:func:`edge_surface_load`).

    At the largest chip thickness of the engagement, ``h = fz max(sin phi)`` over
    ``entry_rad <= phi <= exit_rad``.

    Parameters
    ----------
    coefficients
        Cutting (Pa) and edge (N/m) coefficients.
    feed_per_tooth_m
        Feed per tooth fz, m (> 0).
    entry_rad, exit_rad
        Immersion angles of the engagement, rad
        (:func:`~cnctwin.mechanics.engagement.immersion_angles`).
    contact_length_m
        Contact length of the edge on the surface 2a, m.

    Returns
    -------
    SurfaceLoad
        P and Q in N/m, Hertzian.
    """
    if not (math.isfinite(feed_per_tooth_m) and 0.0 < feed_per_tooth_m <= 0.01):
        raise ConfigError(f"feed per tooth = {feed_per_tooth_m!r} m; give 0 < fz <= 0.01 m (10 mm)")
    lo, hi = max(entry_rad, 0.0), min(exit_rad, math.pi)
    if not hi > lo:
        raise ConfigError(
            f"immersion {entry_rad!r} .. {exit_rad!r} rad; give 0 <= entry < exit <= pi"
        )
    sine = 1.0 if lo <= math.pi / 2 <= hi else max(math.sin(lo), math.sin(hi))
    return edge_surface_load(coefficients, feed_per_tooth_m * sine, contact_length_m)


def loading_stresses(
    load: SurfaceLoad,
    x_m: ArrayLike,
    z_m: ArrayLike,
    segments: int = DEFAULT_SEGMENTS,
) -> LoadingStresses:
    """The elastic field of a surface load (Johnson 1985, Eq. 2.15, 2.19, 2.23; plane strain).

    Parameters
    ----------
    load
        The surface load (N/m, m).
    x_m
        Positions along x relative to the contact centre, m.
    z_m
        Depths, m (>= 0).
    segments
        Linear segments of a Hertzian load (a uniform load is exact with one).

    Returns
    -------
    LoadingStresses
        sigma_xx, sigma_zz, tau_xz in Pa on the grid ``x_m`` x ``z_m``.
    """
    x = np.atleast_1d(np.asarray(x_m, dtype=float))
    z = np.atleast_1d(np.asarray(z_m, dtype=float))
    if x.ndim != 1 or z.ndim != 1 or not (np.all(np.isfinite(x)) and np.all(np.isfinite(z))):
        raise ConfigError("loading_stresses: give finite 1-D positions x_m and depths z_m")
    if np.any(z < 0.0):
        raise ConfigError(f"depth {float(z.min())!r} m; give depths >= 0 (into the part)")
    if segments < 1:
        raise ConfigError(f"segments = {segments!r}; give at least 1")
    s, shape = _load_shape(load, segments)
    u = np.broadcast_to(x[:, None, None] - s[None, None, :], (x.size, z.size, s.size))
    zz = np.broadcast_to(z[None, :, None], u.shape)
    i0, i1 = _antiderivatives(u, zz)
    # a segment's integral of (A + B s) G(x - s) ds = c0 [I0]_b^a + c1 [I1]_b^a, with
    # u_a = x - s_k, u_b = x - s_(k+1), c0 = A + B x, c1 = -B
    slope = np.diff(shape) / np.diff(s)
    offset = shape[:-1] - slope * s[:-1]
    c0 = offset[None, None, :] + slope[None, None, :] * x[:, None, None]
    c1 = -slope[None, None, :]
    factor = -2.0 / math.pi

    def integral(kernel: int) -> NDArray[np.float64]:
        d0 = i0[kernel][..., :-1] - i0[kernel][..., 1:]
        d1 = i1[kernel][..., :-1] - i1[kernel][..., 1:]
        return np.asarray(np.sum(c0 * d0 + c1 * d1, axis=-1) * factor, dtype=float)

    ga, gb, gc, gd = (integral(k) for k in range(4))
    p, q = load.normal_n_m, load.tangential_n_m
    return LoadingStresses(
        x_m=x,
        z_m=z,
        sigma_xx=p * ga + q * gd,
        sigma_zz=p * gb + q * gc,
        tau_xz=p * gc + q * ga,
    )


def elastic_release(
    sigma_xx: ArrayLike,
    sigma_yy: ArrayLike,
    sigma_zz: ArrayLike,
    temperature_rise_k: ArrayLike,
    material: ElasticMaterial,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Residual sigma_xx, sigma_yy after Ward's release (Eq. 3-5, the M steps summed).

    Relaxes ``sigma_zz`` and the temperature to zero at ``eps_xx^r = eps_yy^r = 0``::

        sigma_ii^r = sigma_ii - (nu sigma_zz - E alpha T) / (1 - nu),   i = x, y

    Parameters
    ----------
    sigma_xx, sigma_yy, sigma_zz
        Loaded stresses, Pa (broadcastable).
    temperature_rise_k
        Temperature rise of the loaded state, K.
    material
        E (Pa), nu, alpha (1/K).

    Returns
    -------
    tuple of arrays
        Residual sigma_xx and sigma_yy, Pa.
    """
    e, nu, alpha = material.youngs_modulus_pa, material.poisson_ratio, material.expansion_per_k
    released = nu * np.asarray(sigma_zz, float) - e * alpha * np.asarray(temperature_rise_k, float)
    change = released / (1.0 - nu)
    return (
        np.asarray(np.asarray(sigma_xx, float) - change, dtype=float),
        np.asarray(np.asarray(sigma_yy, float) - change, dtype=float),
    )


class ElasticMirsModel:
    """Elastic MIRS profiles for one contact, material and depth grid (see the module).

    The contact load is Hertzian: a uniform tangential traction makes the surface stress
    log-singular at the contact's edges (Johnson 1985, Sec. 2.8), so its surface MIRS would be
    a property of the position grid. The loading field is linear in the loads, so the fields of
    a unit normal and a unit tangential load are computed once; each :meth:`profile` combines
    them (fast enough for the twin's cycle and for a parameter search).

    Parameters
    ----------
    material
        Elastic constants of the workpiece.
    contact_length_m
        Contact length 2a, m.
    depth_m
        Depths of the profile, m (>= 0, increasing).
    positions
        Positions along x scanned for each depth's loaded state (odd: the centre is one),
        spread over ``+-(2a + 2 max depth)``, with the load's nodes added.
    segments
        Linear segments of a Hertzian load.
    """

    def __init__(
        self,
        material: ElasticMaterial,
        contact_length_m: float,
        depth_m: ArrayLike,
        positions: int = DEFAULT_POSITIONS,
        segments: int = DEFAULT_SEGMENTS,
    ) -> None:
        z = np.atleast_1d(np.asarray(depth_m, dtype=float))
        if z.ndim != 1 or z.size == 0 or not np.all(np.isfinite(z)):
            raise ConfigError("depth_m: give a 1-D list of finite depths in m")
        if np.any(z < 0.0) or np.any(np.diff(z) <= 0.0):
            raise ConfigError("depth_m: give depths >= 0 m in increasing order")
        if positions < 1:
            raise ConfigError(f"positions = {positions!r}; give at least 1")
        unit_p = SurfaceLoad(1.0, 0.0, contact_length_m)
        span = 2.0 * unit_p.half_length_m + 2.0 * float(z.max())
        # the load's nodes join the scan: the surface stress of a tangential load peaks at the
        # contact's edge, which an even grid would miss by up to its spacing
        nodes, _ = _load_shape(unit_p, segments)
        x = np.union1d(np.linspace(-span, span, positions), nodes)
        self.material = material
        self.contact_length_m = contact_length_m
        self.depth_m = z
        self.x_m = x
        self._normal = loading_stresses(unit_p, x, z, segments)
        unit_q = SurfaceLoad(0.0, 1.0, contact_length_m)
        self._tangential = loading_stresses(unit_q, x, z, segments)

    def profile(
        self,
        normal_n_m: float,
        tangential_n_m: float,
        temperature_rise_k: ArrayLike | None = None,
    ) -> ResidualStressProfile:
        """The elastic MIRS profile of the loads P, Q (N/m) and a temperature rise.

        Parameters
        ----------
        normal_n_m, tangential_n_m
            P (>= 0) and Q, N/m.
        temperature_rise_k
            Temperature rise of the layer at each depth, K (one per depth), or ``None``.
        """
        SurfaceLoad(normal_n_m, tangential_n_m, self.contact_length_m)  # checks P and Q
        z = self.depth_m
        if temperature_rise_k is None:
            t = np.zeros_like(z)
        else:
            t = np.atleast_1d(np.asarray(temperature_rise_k, dtype=float))
            if t.shape != z.shape or not np.all(np.isfinite(t)):
                raise ConfigError(
                    f"temperature_rise_k: give {z.size} finite values in K, one per depth"
                )
        n, q = self._normal, self._tangential
        e = self.material.youngs_modulus_pa
        nu = self.material.poisson_ratio
        alpha = self.material.expansion_per_k
        thermal = (-e * alpha / (1.0 - nu)) * t
        # the loaded state of each depth: the largest von Mises stress of the field
        # P n + Q q over x, with its sigma_xx, sigma_yy, sigma_zz (one compiled pass)
        worst = np.empty(z.size, dtype=np.int64)
        mises, sxx, syy, szz = (np.empty(z.size) for _ in range(4))
        _kernels.loaded_states(
            float(normal_n_m),
            float(tangential_n_m),
            nu,
            thermal,
            n.sigma_xx,
            n.sigma_zz,
            n.tau_xz,
            q.sigma_xx,
            q.sigma_zz,
            q.tau_xz,
            worst,
            mises,
            sxx,
            syy,
            szz,
        )
        rxx, ryy = elastic_release(sxx, syy, szz, t, self.material)
        return ResidualStressProfile(
            depth_m=z,
            sigma_xx_pa=rxx,
            sigma_yy_pa=ryy,
            loaded_x_m=self.x_m[worst],
            loaded_von_mises_pa=mises,
        )


def elastic_mirs(
    load: SurfaceLoad,
    material: ElasticMaterial,
    depth_m: ArrayLike,
    temperature_rise_k: ArrayLike | None = None,
    positions: int = DEFAULT_POSITIONS,
    segments: int = DEFAULT_SEGMENTS,
) -> ResidualStressProfile:
    """The elastic MIRS profile of a Hertzian surface load (Ward 2021, Sec. 3.3; see the module).

    One-off form of :class:`ElasticMirsModel` (which see for the parameters).

    Returns
    -------
    ResidualStressProfile
        sigma_xx and sigma_yy (Pa) per depth, with the loaded states taken.
    """
    if load.distribution != "hertzian":
        raise ConfigError(
            f"elastic_mirs: distribution {load.distribution!r}; the MIRS model takes a "
            "'hertzian' load (a uniform tangential traction is singular at the contact's edges)"
        )
    model = ElasticMirsModel(material, load.contact_length_m, depth_m, positions, segments)
    return model.profile(load.normal_n_m, load.tangential_n_m, temperature_rise_k)


def _load_shape(
    load: SurfaceLoad, segments: int
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Nodes s (m) and the load per unit length at them, for a unit total load (1/m).

    Hertzian: cosine-spaced nodes, the ellipse sampled there and scaled so that the
    piecewise-linear load integrates to exactly 1.
    """
    a = load.half_length_m
    if load.distribution == "uniform":
        return np.array([-a, a]), np.full(2, 0.5 / a)
    s = -a * np.cos(np.linspace(0.0, math.pi, segments + 1))
    shape = np.sqrt(np.clip(1.0 - (s / a) ** 2, 0.0, None))
    total = float(np.sum(0.5 * (shape[1:] + shape[:-1]) * np.diff(s)))
    return s, shape / total


def _antiderivatives(
    u: NDArray[np.float64], z: NDArray[np.float64]
) -> tuple[list[NDArray[np.float64]], list[NDArray[np.float64]]]:
    """Antiderivatives in u of the four Flamant kernels G and of u G (the module's integrals).

    Kernels, r^2 = u^2 + z^2: ``u^2 z / r^4``, ``z^3 / r^4``, ``u z^2 / r^4``, ``u^3 / r^4``;
    theta = atan2(u, z) (which also gives the surface limit z = 0).
    """
    r2 = u * u + z * z
    safe = np.where(r2 > _TINY_R2, r2, 1.0)
    theta = np.arctan2(u, z)
    log_r = 0.5 * np.log(np.maximum(r2, _TINY_R2))
    zu = z * u / safe
    zz = z * z / safe
    i0 = [
        0.5 * theta - 0.5 * zu,
        0.5 * theta + 0.5 * zu,
        -0.5 * zz,
        log_r + 0.5 * zz,
    ]
    i1 = [
        z * (log_r + 0.5 * zz),
        -0.5 * z * zz,
        0.5 * z * theta - 0.5 * z * zu,
        u - 1.5 * z * theta + 0.5 * u * zz,
    ]
    return i0, i1
