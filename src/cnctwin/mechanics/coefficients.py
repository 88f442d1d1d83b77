"""Mechanistic cutting-force coefficients: shear (chip-load) and edge (ploughing) terms.

The linear edge-force model (Altintas, *Manufacturing Automation*, 2nd ed., 2012, ch. 2;
Royandi 2026, Eq. 10-11; Ward 2021, Eq. 1) writes the force on a cutting-edge element of chip
width ``db`` cutting a chip of thickness ``h`` as, in its tangential, radial and axial directions,

    dFt = Ktc h db + Kte db,   dFr = Krc h db + Kre db,   dFa = Kac h db + Kae db.
"""

from __future__ import annotations

import math
from dataclasses import astuple, dataclass

import numpy as np

from cnctwin.errors import ConfigError

__all__ = ["CuttingCoefficients"]

_N_MM2 = 1e6  # Pa per N/mm^2
_N_MM = 1e3  # N/m per N/mm


@dataclass(frozen=True)
class CuttingCoefficients:
    """The six coefficients of the linear edge-force model, in SI units.

    Attributes
    ----------
    ktc, krc, kac
        Tangential, radial and axial shear (cutting) coefficients in Pa (N/m^2).
    kte, kre, kae
        Tangential, radial and axial edge coefficients in N/m.

    Notes
    -----
    Handbooks and papers quote the shear coefficients in N/mm^2 (= MPa) and the edge
    coefficients in N/mm; :meth:`from_n_mm` and :meth:`to_n_mm` convert.
    """

    ktc: float
    krc: float
    kac: float = 0.0
    kte: float = 0.0
    kre: float = 0.0
    kae: float = 0.0

    def __post_init__(self) -> None:
        for name, value in zip(
            ("ktc", "krc", "kac", "kte", "kre", "kae"), astuple(self), strict=True
        ):
            try:
                number = float(value)
            except (TypeError, ValueError):
                number = math.nan
            if not math.isfinite(number):
                raise ConfigError(f"cutting coefficient {name}={value!r}; give a finite number")
            object.__setattr__(self, name, number)

    @classmethod
    def from_n_mm(
        cls,
        ktc_n_mm2: float,
        krc_n_mm2: float,
        kac_n_mm2: float = 0.0,
        kte_n_mm: float = 0.0,
        kre_n_mm: float = 0.0,
        kae_n_mm: float = 0.0,
    ) -> CuttingCoefficients:
        """Coefficients from the customary units: shear terms in N/mm^2, edge terms in N/mm."""
        return cls(
            ktc=float(ktc_n_mm2) * _N_MM2,
            krc=float(krc_n_mm2) * _N_MM2,
            kac=float(kac_n_mm2) * _N_MM2,
            kte=float(kte_n_mm) * _N_MM,
            kre=float(kre_n_mm) * _N_MM,
            kae=float(kae_n_mm) * _N_MM,
        )

    def to_n_mm(self) -> dict[str, float]:
        """The coefficients in customary units, keyed ``ktc_n_mm2`` ... ``kae_n_mm``."""
        return {
            "ktc_n_mm2": self.ktc / _N_MM2,
            "krc_n_mm2": self.krc / _N_MM2,
            "kac_n_mm2": self.kac / _N_MM2,
            "kte_n_mm": self.kte / _N_MM,
            "kre_n_mm": self.kre / _N_MM,
            "kae_n_mm": self.kae / _N_MM,
        }

    def as_array(self) -> np.ndarray:
        """``[ktc, krc, kac, kte, kre, kae]`` as float64 (Pa, Pa, Pa, N/m, N/m, N/m)."""
        # Field by field: dataclasses.astuple deep-copies and costs ~15 us per call, which a
        # twin cycle pays once per step.
        return np.array(
            (self.ktc, self.krc, self.kac, self.kte, self.kre, self.kae), dtype=np.float64
        )
