"""Terrain height surfaces for terrain-aided navigation (spec §9.2).

Two surfaces share one interface (:class:`Terrain`), evaluated at geodetic
``(L, λ)`` in rad (any broadcastable shapes):

* ``height_and_gradient(L, lam) -> (h_T, ∂h_T/∂L, ∂h_T/∂λ)`` in m, m/rad, m/rad — what
  the SITAN Jacobian needs (:mod:`ftnav.sensors.tan`);
* ``height_and_slope(L, lam) -> (h_T, s_E, s_N)``, slopes in metres per metre
  (dimensionless) toward East and North, used for gating and reporting.

:class:`AnalyticTerrain` is the sum-of-sinusoids surface of spec §9.2 with exact
slopes; :class:`GridDem` is a digital elevation model on a (rectilinear) latitude /
longitude grid with bilinear interpolation, loadable from the two real DEMs of
``shared/data/dem_samples`` (:meth:`GridDem.from_npz`) or sampled from an analytic
surface (:meth:`GridDem.sample`).  Points outside a grid give NaN.
"""

from __future__ import annotations

import math
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal, Protocol, runtime_checkable

import numpy as np

from ftnav.nav.earth import radii
from ftnav.sensors.base import check_choice, check_float

__all__ = ["Terrain", "AnalyticTerrain", "GridDem"]

_DEG = math.pi / 180.0


@runtime_checkable
class Terrain(Protocol):
    """A terrain height surface h_T(L, λ) (module docstring)."""

    def height_and_gradient(self, L, lam) -> tuple[np.ndarray, np.ndarray, np.ndarray]: ...

    def height_and_slope(self, L, lam) -> tuple[np.ndarray, np.ndarray, np.ndarray]: ...


def _tuple(prefix: str, name: str, value, *, positive: bool = False) -> tuple[float, ...]:
    try:
        a = np.atleast_1d(np.asarray(value, dtype=float))
    except (TypeError, ValueError):
        raise ValueError(f"{prefix}.{name}: expected a list of numbers, got {value!r}") from None
    if a.ndim != 1 or a.size < 1 or not np.all(np.isfinite(a)):
        raise ValueError(
            f"{prefix}.{name}: expected a non-empty list of finite numbers, got {value!r}"
        )
    if positive and np.any(a <= 0.0):
        raise ValueError(f"{prefix}.{name}: must be > 0, got {value!r}")
    return tuple(float(x) for x in a)


@dataclass(frozen=True, slots=True)
class AnalyticTerrain:
    """Sum-of-sinusoids terrain with exact slopes (spec §9.2 [A]).

    ``h_T = h0 + Σ_k A_k sin(2πE/λ_Ek + φ_k) cos(2πN/λ_Nk + ψ_k)``, where (E, N) are
    local flat-earth metres about the origin ``(L0, λ0)``: ``E = (λ − λ0) R_N(L0) cos L0``
    and ``N = (L − L0) R_M(L0)`` (radii at zero height, fixed at the origin).  The surface
    is therefore a smooth function of (L, λ) everywhere and ``∂h_T/∂L = R_M(L0) ∂h_T/∂N``,
    ``∂h_T/∂λ = R_N(L0) cos L0 ∂h_T/∂E`` exactly.

    Attributes
    ----------
    origin_lat_deg, origin_lon_deg : float, deg, origin of (E, N).
    h0_m : float, m, mean height.
    amplitudes_m : (k,) m.  wavelengths_e_m, wavelengths_n_m : (k,) m, > 0.
    phases_e, phases_n : (k,) rad, phases φ_k, ψ_k.
    """

    origin_lat_deg: float
    origin_lon_deg: float
    h0_m: float
    amplitudes_m: tuple[float, ...]
    wavelengths_e_m: tuple[float, ...]
    wavelengths_n_m: tuple[float, ...]
    phases_e: tuple[float, ...]
    phases_n: tuple[float, ...]

    def __post_init__(self):
        p = "terrain"
        lat = check_float(p, "origin_lat_deg", self.origin_lat_deg)
        if abs(lat) >= 89.0:
            raise ValueError(f"{p}.origin_lat_deg: must be within ±89°, got {lat!r}")
        object.__setattr__(self, "origin_lat_deg", lat)
        object.__setattr__(
            self, "origin_lon_deg", check_float(p, "origin_lon_deg", self.origin_lon_deg)
        )
        object.__setattr__(self, "h0_m", check_float(p, "h0_m", self.h0_m))
        n = None
        for name in ("amplitudes_m", "wavelengths_e_m", "wavelengths_n_m", "phases_e", "phases_n"):
            t = _tuple(p, name, getattr(self, name), positive=name.startswith("wave"))
            if n is not None and len(t) != n:
                raise ValueError(f"{p}.{name}: expected {n} values like amplitudes_m, got {len(t)}")
            n = len(t)
            object.__setattr__(self, name, t)

    @classmethod
    def random(
        cls,
        rng: np.random.Generator,
        origin_lat_deg: float,
        origin_lon_deg: float,
        n_waves: int = 6,
        h0_m: float = 300.0,
        amplitude_range_m: tuple[float, float] = (10.0, 80.0),
        wavelength_range_m: tuple[float, float] = (500.0, 5000.0),
    ) -> AnalyticTerrain:
        """A random surface (spec §9.2): A_k, λ_Ek, λ_Nk uniform in the ranges, phases
        uniform in [0, 2π)."""
        if not isinstance(n_waves, int) or n_waves < 1:
            raise ValueError(f"terrain.n_waves: expected an integer >= 1, got {n_waves!r}")
        a_lo, a_hi = amplitude_range_m
        w_lo, w_hi = wavelength_range_m
        if not (0.0 < w_lo <= w_hi):
            raise ValueError(
                f"terrain.wavelength_range_m: expected 0 < low <= high, got {wavelength_range_m!r}"
            )
        return cls(
            origin_lat_deg,
            origin_lon_deg,
            h0_m,
            tuple(rng.uniform(a_lo, a_hi, n_waves)),
            tuple(rng.uniform(w_lo, w_hi, n_waves)),
            tuple(rng.uniform(w_lo, w_hi, n_waves)),
            tuple(rng.uniform(0.0, 2.0 * np.pi, n_waves)),
            tuple(rng.uniform(0.0, 2.0 * np.pi, n_waves)),
        )

    @property
    def metres_per_rad(self) -> tuple[float, float]:
        """``(R_M(L0), R_N(L0) cos L0)``: metres of N per rad of L and of E per rad of λ."""
        L0 = self.origin_lat_deg * _DEG
        RM, RN = radii(L0, 0.0)
        return float(RM), float(RN * math.cos(L0))

    def local_metres(self, L, lam) -> tuple[np.ndarray, np.ndarray]:
        """Flat-earth ``(E, N)`` in metres about the origin (class docstring)."""
        mN, mE = self.metres_per_rad
        dlam = (np.asarray(lam, dtype=float) - self.origin_lon_deg * _DEG + np.pi) % (
            2.0 * np.pi
        ) - np.pi
        return dlam * mE, (np.asarray(L, dtype=float) - self.origin_lat_deg * _DEG) * mN

    def _height_and_slope_en(self, L, lam):
        E, N = self.local_metres(L, lam)
        a = 2.0 * np.pi / np.array(self.wavelengths_e_m)
        b = 2.0 * np.pi / np.array(self.wavelengths_n_m)
        A = np.array(self.amplitudes_m)
        ue = E[..., None] * a + np.array(self.phases_e)
        un = N[..., None] * b + np.array(self.phases_n)
        se, ce, sn, cn = np.sin(ue), np.cos(ue), np.sin(un), np.cos(un)
        h = self.h0_m + np.sum(A * se * cn, -1)
        s_E = np.sum(A * a * ce * cn, -1)
        s_N = -np.sum(A * b * se * sn, -1)
        return h, s_E, s_N

    def height_and_slope(self, L, lam) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(h_T (m), ∂h_T/∂E, ∂h_T/∂N)`` exactly, slopes in the flat (E, N) metres."""
        return self._height_and_slope_en(L, lam)

    def height_and_gradient(self, L, lam) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(h_T (m), ∂h_T/∂L (m/rad), ∂h_T/∂λ (m/rad))`` exactly."""
        h, s_E, s_N = self._height_and_slope_en(L, lam)
        mN, mE = self.metres_per_rad
        return h, s_N * mN, s_E * mE

    def max_derivatives(self) -> tuple[float, float, float, float]:
        """Bounds ``(max|h_EE|, max|h_NN|, max|h_EEE|, max|h_NNN|)`` (Σ A_k a_k², …)."""
        A = np.array(self.amplitudes_m)
        a = 2.0 * np.pi / np.array(self.wavelengths_e_m)
        b = 2.0 * np.pi / np.array(self.wavelengths_n_m)
        return (
            float(np.sum(A * a**2)),
            float(np.sum(A * b**2)),
            float(np.sum(A * a**3)),
            float(np.sum(A * b**3)),
        )


def _readonly(a) -> np.ndarray:
    a = np.array(a, dtype=float)
    a.flags.writeable = False
    return a


@dataclass(frozen=True, slots=True, eq=False)
class GridDem:
    """Digital elevation model on a rectilinear geodetic grid (spec §9.2).

    Heights between nodes are bilinear in (latitude, longitude).  Slopes (``slope``):

    * ``"central"`` (default, spec §9.2): central differences of the interpolated
      height with steps equal to the local grid spacing (one-sided at the grid edge);
    * ``"plane_fit"``: weighted least-squares plane ``h = c + s_E dE + s_N dN`` through
      the interpolated heights on a square pattern of points spaced by the grid spacing
      over ``±plane_fit_radius_m`` (E and N) around the point, Gaussian weights
      ``exp(−(dE² + dN²)/(2σ²))`` with ``σ = plane_fit_radius_m/2`` (SITAN-style
      stochastic linearization; Mok & Bang 2013).  Pattern points off the grid are
      dropped.  Exact on a surface that is a plane in (L, λ).

    Gradients in m/rad; slopes converted to metres per metre with ``R_M(L)`` and
    ``R_N(L) cos L`` (zero height) at the point.  Outside the grid every output is NaN.

    Attributes
    ----------
    lat_deg : (ny,) strictly increasing.  lon_deg : (nx,) strictly increasing, in degrees.
    height_m : (ny, nx) m, row i at ``lat_deg[i]``.
    slope : ``"central"`` or ``"plane_fit"``.  plane_fit_radius_m : float, m, > 0.
    """

    lat_deg: np.ndarray
    lon_deg: np.ndarray
    height_m: np.ndarray
    slope: Literal["central", "plane_fit"] = "central"
    plane_fit_radius_m: float = 150.0
    _offsets: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        p = "dem"
        lat, lon = _readonly(self.lat_deg), _readonly(self.lon_deg)
        h = _readonly(self.height_m)
        for name, a in (("lat_deg", lat), ("lon_deg", lon)):
            if a.ndim != 1 or a.size < 2 or not np.all(np.isfinite(a)):
                raise ValueError(f"{p}.{name}: expected >= 2 finite values, got shape {a.shape}")
            if np.any(np.diff(a) <= 0.0):
                raise ValueError(f"{p}.{name}: must be strictly increasing")
        if h.shape != (lat.size, lon.size):
            raise ValueError(
                f"{p}.height_m: expected shape ({lat.size}, {lon.size}), got {h.shape}"
            )
        check_choice(p, "slope", self.slope, ("central", "plane_fit"))
        radius = check_float(p, "plane_fit_radius_m", self.plane_fit_radius_m, low=0.0, strict=True)
        object.__setattr__(self, "lat_deg", lat)
        object.__setattr__(self, "lon_deg", lon)
        object.__setattr__(self, "height_m", h)
        object.__setattr__(self, "plane_fit_radius_m", radius)
        # plane-fit pattern: offsets (dE, dN) in metres spaced by the finest grid spacing
        Lm = 0.5 * (lat[0] + lat[-1]) * _DEG
        RM, RN = radii(Lm, 0.0)
        step = min(
            np.min(np.diff(lat)) * _DEG * RM, np.min(np.diff(lon)) * _DEG * RN * math.cos(Lm)
        )
        k = max(1, math.ceil(radius / step))
        g = np.linspace(-radius, radius, 2 * k + 1)
        dE, dN = np.meshgrid(g, g, indexing="xy")
        object.__setattr__(self, "_offsets", _readonly(np.stack([dE.ravel(), dN.ravel()], -1)))

    # ------------------------------------------------------------------ constructors
    @classmethod
    def from_npz(cls, path: str | Path, **options) -> GridDem:
        """Load a DEM saved as ``.npz`` (read with ``allow_pickle=False``).

        Recognized layouts:

        * ``height_m``, ``lat_deg``, ``lon_deg`` (this class's own fields);
        * matplotlib ``jacksboro_fault_dem.npz``: ``elevation`` (ny, nx) with the scalar
          extent ``xmin, xmax`` (west, east edges) and ``ymin, ymax``; ``ymin`` is the
          **northern** edge there and row 0 the northern row.  The extent is taken as the
          outer cell edges (it spans exactly ny × dy), so node i is the cell centre; rows
          are flipped so that latitude increases;
        * matplotlib ``topobathy.npz``: ``topo`` (ny, nx), ``latitude`` (ny,) (non-uniform),
          ``longitude`` (nx,) in degrees east 0–360 (converted to −180..180).

        ``options`` are passed on (``slope``, ``plane_fit_radius_m``).

        Raises
        ------
        ValueError
            ``"<path>: missing key '<key>'"`` or a corrupt/unreadable file.
        """
        path = Path(path)
        if not path.is_file():
            raise ValueError(f"{path}: cannot read the DEM (no such file)")
        # an .npz is a zip archive: anything else (an .npy, text, a pickle) is refused
        # before NumPy, whose message for it suggests unpickling
        if not zipfile.is_zipfile(path):
            raise ValueError(f"{path}: cannot read the DEM (not an .npz archive)")
        try:
            with np.load(path, allow_pickle=False) as d:
                data = {k: d[k] for k in d.files}
        except OSError as exc:
            raise ValueError(f"{path}: cannot read the DEM ({exc.strerror or exc})") from None
        except (ValueError, EOFError, zipfile.BadZipFile):
            raise ValueError(f"{path}: cannot read the DEM (a damaged archive)") from None

        def need(*keys):
            for k in keys:
                if k not in data:
                    raise ValueError(f"{path}: missing key {k!r}")
            return [np.asarray(data[k], dtype=float) for k in keys]

        if "elevation" in data:
            z, xmin, xmax, ymin, ymax = need("elevation", "xmin", "xmax", "ymin", "ymax")
            if z.ndim != 2:
                raise ValueError(f"{path}: 'elevation' must be 2-D, got shape {z.shape}")
            ny, nx = z.shape
            lon = xmin + (np.arange(nx) + 0.5) * (xmax - xmin) / nx
            lat = ymin + (np.arange(ny) + 0.5) * (ymax - ymin) / ny  # row 0 at ymin
            if lat[-1] < lat[0]:
                lat, z = lat[::-1], z[::-1]
            return cls(lat, lon, z, **options)
        if "topo" in data:
            z, lat, lon = need("topo", "latitude", "longitude")
            lon = (lon + 180.0) % 360.0 - 180.0
            if lat.ndim == 1 and lat.size > 1 and lat[-1] < lat[0]:
                lat, z = lat[::-1], z[::-1]
            return cls(lat, lon, z, **options)
        z, lat, lon = need("height_m", "lat_deg", "lon_deg")
        return cls(lat, lon, z, **options)

    @classmethod
    def sample(
        cls,
        terrain: Terrain,
        lat_deg: tuple[float, float],
        lon_deg: tuple[float, float],
        spacing_m: float = 30.0,
        **options,
    ) -> GridDem:
        """Sample a surface on a regular grid of ``spacing_m`` metres (at the mid latitude).

        The grid starts at the low corner and covers the extent (last node ≥ high end).
        """
        spacing = check_float("dem", "spacing_m", spacing_m, low=0.0, strict=True)
        (la0, la1), (lo0, lo1) = lat_deg, lon_deg
        if not (la1 > la0 and lo1 > lo0):
            raise ValueError("dem.lat_deg/lon_deg: expected (low, high) with low < high")
        Lm = 0.5 * (la0 + la1) * _DEG
        RM, RN = radii(Lm, 0.0)
        dlat = spacing / RM / _DEG
        dlon = spacing / (RN * math.cos(Lm)) / _DEG
        lat = la0 + dlat * np.arange(math.ceil((la1 - la0) / dlat - 1e-9) + 1)
        lon = lo0 + dlon * np.arange(math.ceil((lo1 - lo0) / dlon - 1e-9) + 1)
        LL, LA = np.meshgrid(lat * _DEG, lon * _DEG, indexing="ij")
        h = terrain.height_and_gradient(LL, LA)[0]
        return cls(lat, lon, h, **options)

    # ------------------------------------------------------------------ evaluation
    def height(self, L, lam) -> np.ndarray:
        """Bilinear height (m) at (L, λ) in rad; NaN outside the grid."""
        lat = np.asarray(L, dtype=float) / _DEG
        lon = np.asarray(lam, dtype=float) / _DEG
        lat, lon = np.broadcast_arrays(lat, lon)
        gl, go, z = self.lat_deg, self.lon_deg, self.height_m
        i = np.clip(np.searchsorted(gl, lat, side="right") - 1, 0, gl.size - 2)
        j = np.clip(np.searchsorted(go, lon, side="right") - 1, 0, go.size - 2)
        ty = (lat - gl[i]) / (gl[i + 1] - gl[i])
        tx = (lon - go[j]) / (go[j + 1] - go[j])
        h = (1 - ty) * ((1 - tx) * z[i, j] + tx * z[i, j + 1]) + ty * (
            (1 - tx) * z[i + 1, j] + tx * z[i + 1, j + 1]
        )
        inside = (lat >= gl[0]) & (lat <= gl[-1]) & (lon >= go[0]) & (lon <= go[-1])
        return np.where(inside, h, np.nan)

    def contains(self, L, lam) -> np.ndarray:
        """Boolean mask of the points (rad) inside the grid."""
        lat = np.asarray(L, dtype=float) / _DEG
        lon = np.asarray(lam, dtype=float) / _DEG
        return (
            (lat >= self.lat_deg[0])
            & (lat <= self.lat_deg[-1])
            & (lon >= self.lon_deg[0])
            & (lon <= self.lon_deg[-1])
        )

    def _central(self, L, lam):
        lat = L / _DEG
        lon = lam / _DEG
        gl, go = self.lat_deg, self.lon_deg
        i = np.clip(np.searchsorted(gl, lat, side="right") - 1, 0, gl.size - 2)
        j = np.clip(np.searchsorted(go, lon, side="right") - 1, 0, go.size - 2)
        dlat = (gl[i + 1] - gl[i]) * _DEG
        dlon = (go[j + 1] - go[j]) * _DEG
        Lp = np.minimum(L + dlat, gl[-1] * _DEG)
        Lm = np.maximum(L - dlat, gl[0] * _DEG)
        lp = np.minimum(lam + dlon, go[-1] * _DEG)
        lm = np.maximum(lam - dlon, go[0] * _DEG)
        gL = (self.height(Lp, lam) - self.height(Lm, lam)) / (Lp - Lm)
        gl_ = (self.height(L, lp) - self.height(L, lm)) / (lp - lm)
        return gL, gl_

    def _plane_fit(self, L, lam):
        RM, RN = radii(L, 0.0)
        mN, mE = RM, RN * np.cos(L)
        dE, dN = self._offsets[:, 0], self._offsets[:, 1]
        hs = self.height(L[..., None] + dN / mN[..., None], lam[..., None] + dE / mE[..., None])
        sigma = 0.5 * self.plane_fit_radius_m
        w = np.exp(-(dE**2 + dN**2) / (2.0 * sigma**2)) * np.isfinite(hs)
        hs = np.where(np.isfinite(hs), hs, 0.0)
        X = np.stack(np.broadcast_arrays(np.ones_like(dE), dE, dN), -1)  # (n, 3)
        A = np.einsum("...n,ni,nj->...ij", w, X, X)
        y = np.einsum("...n,ni,...n->...i", w, X, hs)
        ok = np.linalg.det(A) > 0.0
        A = np.where(ok[..., None, None], A, np.eye(3))
        beta = np.linalg.solve(A, y[..., None])[..., 0]
        beta = np.where(ok[..., None], beta, np.nan)
        return beta[..., 2] * mN, beta[..., 1] * mE

    def height_and_gradient(self, L, lam) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(h_T (m), ∂h_T/∂L (m/rad), ∂h_T/∂λ (m/rad))``; NaN outside the grid."""
        L, lam = np.broadcast_arrays(np.asarray(L, dtype=float), np.asarray(lam, dtype=float))
        h = self.height(L, lam)
        gL, glam = self._central(L, lam) if self.slope == "central" else self._plane_fit(L, lam)
        inside = np.isfinite(h)
        return h, np.where(inside, gL, np.nan), np.where(inside, glam, np.nan)

    def height_and_slope(self, L, lam) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(h_T (m), s_E, s_N)`` with slopes in metres per metre at the point."""
        L, lam = np.broadcast_arrays(np.asarray(L, dtype=float), np.asarray(lam, dtype=float))
        h, gL, glam = self.height_and_gradient(L, lam)
        RM, RN = radii(L, 0.0)
        return h, glam / (RN * np.cos(L)), gL / RM
