"""Eigenstructure of the static 9-state SINS error model (spec §8.3, §8.6 d).

Oracle: the classical closed forms for a stationary INS at latitude L: the Schuler
frequency split by the Foucault effect ``±i(ω_s ± ω_ie sin L)``, the Earth-rate mode
``±iω_ie``, a zero (longitude is not observable in its own dynamics) and the real
vertical-channel pair ``±√(2g/R)``, with ``ω_s = √(g/R)`` and ``R = √(R_M R_N)``.
The closed forms neglect the small couplings, so they hold to about 1e-3 (spec
observed 1.3e-3); the bound is 5e-3 relative.
"""

from __future__ import annotations

import numpy as np
import pytest

from ftnav.nav.earth import OMEGA_IE, gravity, radii
from ftnav.nav.error_model import ErrorModelParams, continuous_model

DEG = np.pi / 180.0


def static_F(L, h=0.0):
    g = gravity(L, h)
    F = continuous_model(
        L, 0.0, h, np.zeros(3), np.array([0.0, 0.0, g]), np.eye(3), ErrorModelParams()
    ).F
    return F[:9, :9]


def closed_form(L, h=0.0):
    """(oscillation frequencies ascending, real root) of spec §8.6 (d)."""
    RMh, RNh = radii(L, h)
    R = np.sqrt(RMh * RNh)
    g = gravity(L, h)
    w_s = np.sqrt(g / R)
    w_f = OMEGA_IE * np.sin(L)
    return np.sort([OMEGA_IE, w_s - w_f, w_s + w_f]), np.sqrt(2.0 * g / R)


@pytest.mark.parametrize("lat_deg", [32.0, -10.0, 60.0])
def test_static_eigenvalues_match_closed_forms(lat_deg):
    L = lat_deg * DEG
    ev = np.linalg.eigvals(static_F(L))
    osc_ref, real_ref = closed_form(L)
    real = np.sort(ev[np.abs(ev.imag) < 1e-9 * OMEGA_IE].real)
    osc = ev[np.abs(ev.imag) >= 1e-9 * OMEGA_IE]
    assert real.shape == (3,) and osc.shape == (6,)
    # undamped: the oscillatory modes lie on the imaginary axis
    assert np.abs(osc.real).max() < 1e-12 * OMEGA_IE
    freqs = np.sort(osc.imag[osc.imag > 0])
    np.testing.assert_allclose(np.sort(osc.imag[osc.imag < 0]), -freqs[::-1], rtol=1e-12)
    np.testing.assert_allclose(freqs, osc_ref, rtol=5e-3)
    # vertical channel: ±√(2g/R) and the zero of the longitude state
    np.testing.assert_allclose(real[[0, 2]], [-real_ref, real_ref], rtol=5e-3)
    assert abs(real[1]) < 1e-12 * OMEGA_IE


def test_32N_values_quoted_in_spec():
    """Spec §8.6 (d) [V]: ±1.2031e-3 i, ±1.2804e-3 i, ±7.292e-5 i, 0, ±1.754e-3 (1/s)."""
    ev = np.linalg.eigvals(static_F(32.0 * DEG))
    np.testing.assert_allclose(
        np.sort(ev.imag[ev.imag > 1e-9]), [7.292e-5, 1.2031e-3, 1.2804e-3], rtol=1e-4
    )
    np.testing.assert_allclose(ev.real.max(), 1.754e-3, rtol=1e-3)
    osc_ref, real_ref = closed_form(32.0 * DEG)
    freqs = np.sort(ev.imag[ev.imag > 1e-9])
    # the spec's observed worst relative deviation from the closed forms is 1.3e-3
    assert np.abs(freqs / osc_ref - 1.0).max() < 2e-3


def test_missing_coriolis_factor_breaks_the_foucault_split():
    """The check can fail: Coriolis ``ω_ie×`` instead of ``2ω_ie×`` in F_vv (static case,
    where F_vv = −[2ω_ie×]) moves the Schuler pair off ``ω_s ± ω_ie sin L``."""
    L = 32.0 * DEG
    F = static_F(L)
    F[3:6, 3:6] *= 0.5
    ev = np.linalg.eigvals(F)
    freqs = np.sort(ev.imag[ev.imag > 1e-9 * OMEGA_IE])
    osc_ref, _ = closed_form(L)
    assert freqs.shape != osc_ref.shape or not np.allclose(freqs, osc_ref, rtol=5e-3)
