"""GNSS measurement rows are East, North, Up for position as for velocity (conventions.md).

Closed form: a receiver whose position reads 10 m too far north and 4 m too far east
(an error of the device's own reading, ``z = INS − aid`` changes by −e) gives
``z = [−4, −10, 0, ...]`` at the true position, and the position rows of H map the
latitude, longitude and height errors to metres on the North, East, Up rows.
"""

from __future__ import annotations

import numpy as np

from ftnav.nav.attitude import euler_to_quat
from ftnav.nav.earth import radii
from ftnav.sensors import AidTruth, Gnss


def test_position_rows_are_east_north_up():
    g = Gnss(pos_markov_sigma_m=0.0, vel_markov_sigma_m_s=0.0)
    assert g.components == ("pos_E", "pos_N", "pos_U", "vel_E", "vel_N", "vel_U")
    p = np.array([[np.radians(34.0), np.radians(108.0), 500.0]])
    v = np.array([[100.0, 50.0, 1.0]])
    truth = AidTruth(np.array([1.0]), p, v, euler_to_quat(np.zeros((1, 3))))
    e = np.zeros((1, 1, 6))
    e[0, 0, :3] = [4.0, 10.0, 0.0]  # East 4 m, North 10 m
    raw = g.output(truth, e, np.zeros((1, 0)))[:, 0]
    lin = g.measure(truth.q, v, p, raw)
    np.testing.assert_allclose(lin.z[0], [-4.0, -10.0, 0.0, 0.0, 0.0, 0.0], atol=1e-6)
    RM, RN = radii(p[0, 0], p[0, 2])
    H = lin.H[0]
    np.testing.assert_allclose(H[0, 7], RN * np.cos(p[0, 0]))  # East row <- dlambda
    np.testing.assert_allclose(H[1, 6], RM)  # North row <- dL
    assert H[2, 8] == 1.0 and H[0, 6] == 0.0 and H[1, 7] == 0.0


def test_the_default_markov_error_is_augmented_not_folded_into_R():
    g = Gnss()
    assert g.markov == "augment" and g.private is not None
    np.testing.assert_allclose(np.diag(g.R), [1.0] * 3 + [0.02**2] * 3)  # white only
    assert Gnss(pos_markov_sigma_m=0.0, vel_markov_sigma_m_s=0.0).private is None
