"""Bad aiding-sensor inputs raise ValueError naming the field (spec §9; style: tests 6)."""

from __future__ import annotations

import numpy as np
import pytest

from ftnav.nav.attitude import euler_to_quat
from ftnav.sensors import (
    AidTruth,
    AnalyticTerrain,
    Barometer,
    Doppler,
    Gnss,
    GridDem,
    StarTracker,
    Tan,
)

TERRAIN = AnalyticTerrain.random(np.random.default_rng(0), 32.0, 118.0)

BAD_PARAMETERS = [
    (Gnss, {"pos_markov_sigma_m": -1.0}, "gnss.pos_markov_sigma_m"),
    (Gnss, {"pos_markov_sigma_m": (1.0, 2.0)}, "gnss.pos_markov_sigma_m"),
    (Gnss, {"vel_markov_sigma_m_s": float("nan")}, "gnss.vel_markov_sigma_m_s"),
    (Gnss, {"pos_markov_tau_s": 0.0}, "gnss.pos_markov_tau_s"),
    (Gnss, {"vel_markov_tau_s": (100.0, -1.0, 100.0)}, "gnss.vel_markov_tau_s"),
    (Gnss, {"pos_white_sigma_m": -0.1}, "gnss.pos_white_sigma_m"),
    (Gnss, {"markov": "lumped"}, "gnss.markov"),
    (Gnss, {"pos_sigma_m": 0.0}, "gnss.pos_sigma_m"),
    (Gnss, {"dt": 0.0}, "gnss.dt"),
    (Gnss, {"name": ""}, "name"),
    (Gnss, {"name": "gps1", "pos_markov_tau_s": -5.0}, "gps1.pos_markov_tau_s"),
    (Doppler, {"scale_sigma": -1e-3}, "dns.scale_sigma"),
    (Doppler, {"markov_tau_s": 0.0}, "dns.markov_tau_s"),
    (Doppler, {"markov_sigma_m_s": "big"}, "dns.markov_sigma_m_s"),
    (Doppler, {"white_sigma_m_s": -1.0}, "dns.white_sigma_m_s"),
    (Doppler, {"states": "full"}, "dns.states"),
    (Doppler, {"attitude_coupling": "yes"}, "dns.attitude_coupling"),
    (Doppler, {"min_speed_m_s": -5.0}, "dns.min_speed_m_s"),
    (Doppler, {"sigma_m_s": -0.1}, "dns.sigma_m_s"),
    (StarTracker, {"sigma_arcsec": -10.0}, "cns.sigma_arcsec"),
    (StarTracker, {"form": "quaternion"}, "cns.form"),
    (StarTracker, {"position_coupling": 1}, "cns.position_coupling"),
    (StarTracker, {"assumed_sigma_arcsec": float("inf")}, "cns.assumed_sigma_arcsec"),
    (Barometer, {"sigma_m": -5.0}, "ads.sigma_m"),
    (Barometer, {"bias_sigma_m": -1.0}, "ads.bias_sigma_m"),
    (Barometer, {"bias_tau_s": 0.0}, "ads.bias_tau_s"),
    (Barometer, {"bias_state": "no"}, "ads.bias_state"),
    (Barometer, {"dt": -1.0}, "ads.dt"),
]


@pytest.mark.parametrize(
    "cls, kwargs, field",
    BAD_PARAMETERS,
    ids=[f"{c.__name__}-{f}-{i}" for i, (c, _, f) in enumerate(BAD_PARAMETERS)],
)
def test_bad_parameter_names_the_field(cls, kwargs, field):
    with pytest.raises(ValueError, match=rf"^{field}: "):
        cls(**kwargs)


@pytest.mark.parametrize(
    "kwargs, field",
    [
        ({"altimeter_sigma_m": -5.0}, "tan.altimeter_sigma_m"),
        ({"map_sigma_m": float("nan")}, "tan.map_sigma_m"),
        ({"min_slope": -0.01}, "tan.min_slope"),
        ({"min_speed_m_s": -1.0}, "tan.min_speed_m_s"),
        ({"sigma_m": 0.0}, "tan.sigma_m"),
        ({"dt": 0.0}, "tan.dt"),
    ],
)
def test_bad_tan_parameter_names_the_field(kwargs, field):
    with pytest.raises(ValueError, match=rf"^{field}: "):
        Tan(TERRAIN, **kwargs)


def test_tan_needs_a_terrain():
    with pytest.raises(ValueError, match=r"^tan\.terrain: "):
        Tan("flat")


@pytest.mark.parametrize(
    "kwargs, field",
    [
        ({"wavelengths_e_m": (100.0, 0.0)}, "terrain.wavelengths_e_m"),
        ({"phases_n": (0.0,)}, "terrain.phases_n"),
        ({"origin_lat_deg": 90.0}, "terrain.origin_lat_deg"),
    ],
)
def test_bad_terrain_names_the_field(kwargs, field):
    base = {
        "origin_lat_deg": 32.0,
        "origin_lon_deg": 118.0,
        "h0_m": 0.0,
        "amplitudes_m": (10.0, 20.0),
        "wavelengths_e_m": (1000.0, 2000.0),
        "wavelengths_n_m": (1500.0, 2500.0),
        "phases_e": (0.0, 1.0),
        "phases_n": (0.5, 2.0),
    }
    with pytest.raises(ValueError, match=rf"^{field}: "):
        AnalyticTerrain(**(base | kwargs))


@pytest.mark.parametrize(
    "kwargs, field",
    [
        ({"lat_deg": np.array([1.0, 0.5, 2.0])}, "dem.lat_deg"),
        ({"height_m": np.zeros((2, 3))}, "dem.height_m"),
        ({"slope": "sobel"}, "dem.slope"),
        ({"plane_fit_radius_m": 0.0}, "dem.plane_fit_radius_m"),
    ],
)
def test_bad_dem_names_the_field(kwargs, field):
    base = {
        "lat_deg": np.array([0.0, 0.5, 1.0]),
        "lon_deg": np.array([0.0, 1.0, 2.0]),
        "height_m": np.zeros((3, 3)),
    }
    with pytest.raises(ValueError, match=rf"^{field}: "):
        GridDem(**(base | kwargs))


def _truth(K: int, dt: float = 1.0) -> AidTruth:
    return AidTruth(
        dt * np.arange(K),
        np.tile([0.5, 2.0, 100.0], (K, 1)),
        np.tile([0.0, 100.0, 0.0], (K, 1)),
        euler_to_quat(np.zeros((K, 3))),
    )


def test_bad_simulation_inputs():
    g = Gnss()
    with pytest.raises(ValueError, match=r"^truth\.t: epochs must be spaced by gnss\.dt"):
        g.simulate_errors(_truth(5, dt=0.5), 0, range(2), 0)
    bad = _truth(5)._replace(p=np.zeros((4, 3)))
    with pytest.raises(ValueError, match=r"^truth\.p: "):
        g.simulate_errors(bad, 0, range(2), 0)
    with pytest.raises(ValueError, match=r"^runs: "):
        g.simulate_errors(_truth(5), 0, [0, 1], 0)
    with pytest.raises(ValueError, match=r"^seed: "):
        g.simulate_errors(_truth(5), -1, range(2), 0)
    with pytest.raises(ValueError, match=r"^errors_metric: "):
        g.output(_truth(5), np.zeros((2, 5, 3)), np.zeros((2, 0)))
    with pytest.raises(ValueError, match=r"^constants: "):
        Doppler().output(_truth(5), np.zeros((2, 5, 2)), np.zeros((2, 0)))
    with pytest.raises(ValueError, match=r"^raw_k: "):
        g.measure(np.zeros((2, 4)), np.zeros((2, 3)), np.zeros((2, 3)), np.zeros((2, 5)))
