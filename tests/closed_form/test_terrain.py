"""Terrain surfaces and DEM loading (spec §9.2), and the SITAN gating.

Bounds for a DEM sampled from the analytic terrain (spacings ΔE, ΔN in metres):

* Height.  Bilinear interpolation is linear interpolation along E then along N;
  linear interpolation over an interval Δ errs by at most ``Δ²/8 · max|f''|``, and the
  two passes add: ``|ĥ − h| ≤ ΔE²/8 · max|h_EE| + ΔN²/8 · max|h_NN| =: e_max``, with
  ``max|h_EE| ≤ Σ A_k a_k²`` (``a_k = 2π/λ_Ek``) and likewise for N.
* Slope.  The central difference with step Δ of the interpolated height is the exact
  central difference (error ``≤ Δ²/6 · max|h'''|``) plus the interpolation errors at
  the two stencil points over 2Δ: ``|ŝ_N − s_N| ≤ ΔN²/6 · Σ A_k b_k³ + e_max/ΔN``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ftnav.nav.attitude import euler_to_quat
from ftnav.nav.earth import radii
from ftnav.sensors import AnalyticTerrain, GridDem, Tan

DEG = np.pi / 180.0
DEM_DIR = Path(__file__).resolve().parents[3] / "shared" / "data" / "dem_samples"
TERRAIN = AnalyticTerrain.random(
    np.random.default_rng(21),
    32.0,
    118.0,
    n_waves=6,
    h0_m=400.0,
    wavelength_range_m=(1000.0, 5000.0),
)


def test_analytic_slopes_match_finite_differences():
    rng = np.random.default_rng(1)
    L = (32.0 + rng.uniform(-0.05, 0.05, 50)) * DEG
    lam = (118.0 + rng.uniform(-0.05, 0.05, 50)) * DEG
    h, gL, glam = TERRAIN.height_and_gradient(L, lam)
    d = 1e-8
    fd_L = (
        TERRAIN.height_and_gradient(L + d, lam)[0] - TERRAIN.height_and_gradient(L - d, lam)[0]
    ) / (2 * d)
    fd_lam = (
        TERRAIN.height_and_gradient(L, lam + d)[0] - TERRAIN.height_and_gradient(L, lam - d)[0]
    ) / (2 * d)
    scale = np.max(np.abs(np.concatenate([gL, glam])))
    np.testing.assert_allclose(gL, fd_L, atol=1e-6 * scale)
    np.testing.assert_allclose(glam, fd_lam, atol=1e-6 * scale)
    # slopes in the terrain's flat metres
    h2, s_E, s_N = TERRAIN.height_and_slope(L, lam)
    mN, mE = TERRAIN.metres_per_rad
    np.testing.assert_array_equal(h, h2)
    np.testing.assert_allclose(s_N * mN, gL, rtol=1e-12)
    np.testing.assert_allclose(s_E * mE, glam, rtol=1e-12)
    assert np.ptp(h) > 10.0 and np.max(np.hypot(s_E, s_N)) > 0.01  # not a flat surface
    # broadcasting: a (3, 1) column against a (4,) row
    assert TERRAIN.height_and_slope(L[:3, None], lam[None, :4])[0].shape == (3, 4)


def test_sampled_dem_reproduces_the_analytic_surface():
    dem = GridDem.sample(TERRAIN, (31.95, 32.05), (117.95, 118.05), spacing_m=30.0)
    mN, mE = TERRAIN.metres_per_rad
    dN = np.max(np.diff(dem.lat_deg)) * DEG * mN
    dE = np.max(np.diff(dem.lon_deg)) * DEG * mE
    assert 29.0 < dN < 31.0 and 29.0 < dE < 31.0
    hEE, hNN, hEEE, hNNN = TERRAIN.max_derivatives()
    e_max = dE**2 / 8 * hEE + dN**2 / 8 * hNN
    rng = np.random.default_rng(2)
    L = rng.uniform(31.96, 32.04, 500) * DEG
    lam = rng.uniform(117.96, 118.04, 500) * DEG
    h_true, gL, glam = TERRAIN.height_and_gradient(L, lam)
    h, gL_dem, glam_dem = dem.height_and_gradient(L, lam)
    assert np.max(np.abs(h - h_true)) <= e_max
    assert np.max(np.abs(h - h_true)) > 1e-3 * e_max  # the grid is really interpolated
    sN_err = np.abs(gL_dem - gL) / mN
    sE_err = np.abs(glam_dem - glam) / mE
    assert np.max(sN_err) <= dN**2 / 6 * hNNN + e_max / dN
    assert np.max(sE_err) <= dE**2 / 6 * hEEE + e_max / dE
    # metres-per-metre slopes use the radii at the point
    _, s_E, s_N = dem.height_and_slope(L, lam)
    RM, RN = radii(L, 0.0)
    np.testing.assert_allclose(s_N, gL_dem / RM)
    np.testing.assert_allclose(s_E, glam_dem / (RN * np.cos(L)))


@pytest.mark.parametrize("slope", ["central", "plane_fit"])
def test_slopes_are_exact_on_a_plane(slope):
    """A surface that is a plane in (L, λ) is reproduced exactly, gradient included."""
    lat = np.linspace(35.0, 35.1, 41)
    lon = np.linspace(-100.0, -99.85, 57) + np.r_[0.0, np.full(56, 1e-4)]  # not uniform
    b_L, b_lam = 1.5e4, -2.5e4  # m/rad
    height = 100.0 + b_L * lat[:, None] * DEG + b_lam * lon[None, :] * DEG
    dem = GridDem(lat, lon, height, slope=slope, plane_fit_radius_m=200.0)
    rng = np.random.default_rng(3)
    L = rng.uniform(35.0, 35.1, 30) * DEG
    lam = rng.uniform(-99.99, -99.85, 30) * DEG
    h, gL, glam = dem.height_and_gradient(L, lam)
    np.testing.assert_allclose(h, 100.0 + b_L * L + b_lam * lam, rtol=1e-12)
    np.testing.assert_allclose(gL, b_L, rtol=1e-8)
    np.testing.assert_allclose(glam, b_lam, rtol=1e-8)


def test_plane_fit_smooths_toward_the_analytic_slope():
    """plane_fit on a curved surface: the weighted LS slope of a symmetric pattern
    ``Σ w dN h / Σ w dN²`` keeps the odd Taylor terms only, so its bias is at most
    ``r² (max|h_NNN|/6 + max|h_EEN|/2)`` (``|dN| ≤ r``), plus the interpolation error
    ``e_max Σ w|dN| / Σ w dN² ≤ e_max/δ`` with δ ≥ Δ/2 the pattern spacing, plus 1e-3 of
    the slope for the metric of the pattern (radii at the point, not at the origin)."""
    r = 90.0
    dem = GridDem.sample(
        TERRAIN,
        (31.98, 32.02),
        (117.98, 118.02),
        spacing_m=30.0,
        slope="plane_fit",
        plane_fit_radius_m=r,
    )
    rng = np.random.default_rng(4)
    L = rng.uniform(31.99, 32.01, 100) * DEG
    lam = rng.uniform(117.99, 118.01, 100) * DEG
    _, gL, _ = TERRAIN.height_and_gradient(L, lam)
    _, gL_fit, _ = dem.height_and_gradient(L, lam)
    mN = TERRAIN.metres_per_rad[0]
    hEE, hNN, _, hNNN = TERRAIN.max_derivatives()
    A = np.array(TERRAIN.amplitudes_m)
    a = 2 * np.pi / np.array(TERRAIN.wavelengths_e_m)
    b = 2 * np.pi / np.array(TERRAIN.wavelengths_n_m)
    hEEN = np.sum(A * a**2 * b)
    e_max = 30.0**2 / 8 * (hEE + hNN)
    bound = r**2 * (hNNN / 6 + hEEN / 2) + 2 * e_max / 30.0 + 1e-3 * np.abs(gL / mN)
    err = np.abs(gL_fit - gL) / mN
    assert np.all(err <= bound)
    assert np.max(err) > 0.0


def test_outside_the_grid_is_nan():
    dem = GridDem.sample(TERRAIN, (31.99, 32.01), (117.99, 118.01), spacing_m=30.0)
    h, gL, glam = dem.height_and_gradient(
        np.array([31.0, 32.0]) * DEG, np.array([118.0, 119.0]) * DEG
    )
    assert np.all(np.isnan(h)) and np.all(np.isnan(gL)) and np.all(np.isnan(glam))
    assert not dem.contains(31.0 * DEG, 118.0 * DEG)
    assert dem.contains(32.0 * DEG, 118.0 * DEG)


def _dem(name: str) -> Path:
    path = DEM_DIR / name
    if not path.exists():
        pytest.skip(f"{path} not available in this checkout")
    return path


def _check_bilinear_cell(dem: GridDem) -> None:
    i, j = dem.lat_deg.size // 2, dem.lon_deg.size // 2
    ty, tx = 0.3, 0.6
    lat = dem.lat_deg[i] + ty * (dem.lat_deg[i + 1] - dem.lat_deg[i])
    lon = dem.lon_deg[j] + tx * (dem.lon_deg[j + 1] - dem.lon_deg[j])
    z = dem.height_m
    corners = np.array([z[i, j], z[i, j + 1], z[i + 1, j], z[i + 1, j + 1]])
    expected = (1 - ty) * ((1 - tx) * corners[0] + tx * corners[1]) + ty * (
        (1 - tx) * corners[2] + tx * corners[3]
    )
    h = dem.height(lat * DEG, lon * DEG)
    np.testing.assert_allclose(h, expected, rtol=1e-9)
    assert corners.min() <= h <= corners.max()


def test_jacksboro_dem_loads_north_up():
    path = _dem("jacksboro_fault_dem.npz")
    dem = GridDem.from_npz(path)
    raw = np.load(path, allow_pickle=False)
    assert dem.height_m.shape == (344, 403)
    assert np.all(np.diff(dem.lat_deg) > 0.0)
    assert 236.0 <= np.nanmin(dem.height_m) and np.nanmax(dem.height_m) <= 1076.0
    assert 36.446 < dem.lat_deg[0] < dem.lat_deg[-1] < 36.733
    assert -84.414 < dem.lon_deg[0] < dem.lon_deg[-1] < -84.077
    np.testing.assert_array_equal(dem.height_m[-1], raw["elevation"][0])  # row 0 is north
    np.testing.assert_allclose(np.diff(dem.lat_deg), float(raw["dy"]), rtol=1e-9)
    _check_bilinear_cell(dem)
    h, s_E, s_N = dem.height_and_slope(36.6 * DEG, -84.2 * DEG)
    assert np.isfinite(h) and np.isfinite(s_E) and np.isfinite(s_N)
    assert np.isnan(dem.height(37.0 * DEG, -84.2 * DEG))


def test_topobathy_dem_loads_with_signed_longitudes():
    path = _dem("topobathy.npz")
    dem = GridDem.from_npz(path, slope="plane_fit", plane_fit_radius_m=5000.0)
    assert dem.height_m.shape == (91, 120)
    assert np.all(np.diff(dem.lat_deg) > 0.0) and np.all(np.diff(dem.lon_deg) > 0.0)
    assert -1437.0 <= np.nanmin(dem.height_m) and np.nanmax(dem.height_m) <= 2205.0
    assert np.nanmin(dem.height_m) < 0.0  # the sea floor is there
    assert -126.0 < dem.lon_deg[0] and dem.lon_deg[-1] < -122.0
    assert 48.0 < dem.lat_deg[0] and dem.lat_deg[-1] < 50.0
    _check_bilinear_cell(dem)
    h, s_E, s_N = dem.height_and_slope(49.0 * DEG, -124.0 * DEG)
    assert np.isfinite(h) and np.isfinite(s_E) and np.isfinite(s_N)


def test_corrupt_npz_names_the_missing_key(tmp_path):
    bad = tmp_path / "bad.npz"
    np.savez(bad, elevation=np.zeros((3, 4)), xmin=0.0, xmax=1.0, ymax=0.0)
    with pytest.raises(ValueError, match=r"bad\.npz.*'ymin'"):
        GridDem.from_npz(bad)
    other = tmp_path / "other.npz"
    np.savez(other, z=np.zeros((3, 4)))
    with pytest.raises(ValueError, match=r"other\.npz.*'height_m'"):
        GridDem.from_npz(other)
    junk = tmp_path / "junk.npz"
    junk.write_bytes(b"not a zip file")
    with pytest.raises(ValueError, match=r"junk\.npz: cannot read the DEM \(not an \.npz"):
        GridDem.from_npz(junk)
    # an .npy ended in an internal error (no context manager), text in NumPy's advice to
    # unpickle it: refused before NumPy reads them, the advice never shown
    npy = tmp_path / "dem.npz"
    with npy.open("wb") as f:
        np.save(f, np.zeros((3, 4)))
    text = tmp_path / "dem.txt"
    text.write_text("1 2 3\n4 5 6\n")
    for path in (npy, text):
        with pytest.raises(ValueError, match=r"cannot read the DEM \(not an \.npz archive\)$"):
            GridDem.from_npz(path)
    with pytest.raises(ValueError, match=r"cannot read the DEM \(no such file\)$"):
        GridDem.from_npz(tmp_path / "missing.npz")


def _tan_epoch(L, lam, clearance, speed):
    h = TERRAIN.height_and_gradient(L, lam)[0] + clearance
    p = np.array([[L, lam, h]])
    v = np.array([[0.0, speed, 0.0]])
    q = euler_to_quat(np.zeros((1, 3)))
    return q, v, p


def test_tan_gating():
    """SITAN is skipped on flat terrain, at low clearance, at taxi speed and off the map."""
    L, lam = 32.0 * DEG, 118.0 * DEG
    tan = Tan(TERRAIN)
    q, v, p = _tan_epoch(L, lam, 500.0, 100.0)
    raw = np.array([500.0])
    slope = np.hypot(*TERRAIN.height_and_slope(L, lam)[1:])
    assert slope > 0.01
    assert tan.measure(q, v, p, raw).valid.all()
    assert not Tan(TERRAIN, min_slope=2 * slope).measure(q, v, p, raw).valid.any()
    q, v, p = _tan_epoch(L, lam, 20.0, 100.0)
    assert not tan.measure(q, v, p, np.array([20.0])).valid.any()
    q, v, p = _tan_epoch(L, lam, 500.0, 10.0)
    assert not tan.measure(q, v, p, raw).valid.any()
    dem = GridDem.sample(TERRAIN, (31.99, 32.01), (117.99, 118.01), spacing_m=30.0)
    lin = Tan(dem).measure(q, np.array([[0.0, 100.0, 0.0]]), p + [0.1, 0.0, 0.0], raw)
    assert not lin.valid.any()
    assert np.all(np.isfinite(lin.z)) and np.all(np.isfinite(lin.H))
