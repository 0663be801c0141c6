"""Bad flight profiles raise one-line errors naming the field (issue 3), CLI exits 2."""

from __future__ import annotations

import copy

import pytest

from ftnav.cli import main
from ftnav.io.common import ScenarioError
from ftnav.io.profile_file import parse_profile

GOOD = {
    "name": "p",
    "imu_rate_hz": 100.0,
    "start": {"lat_deg": 32.0, "lon_deg": 118.0, "h_m": 1000.0, "speed_m_s": 100.0},
    "segments": [
        {"duration_s": 10.0},
        {"duration_s": 5.0, "roll_rate_deg_s": 6.0},
        {"duration_s": 20.0, "yaw_rate_deg_s": "coordinated"},
    ],
}


def _bad(change):
    d = copy.deepcopy(GOOD)
    change(d)
    return d


CASES = [
    (
        "negative duration",
        lambda d: d["segments"][0].update(duration_s=-5.0),
        r"^segments\[0\]\.duration_s: must be > 0",
    ),
    (
        "bank that cannot be flown",
        lambda d: d["segments"][1].update(roll_rate_deg_s=18.0),
        r"^segments\[1\]\.roll_rate_deg_s: bank angle would reach 90\.0°",
    ),
    (
        "latitude beyond 90",
        lambda d: d["start"].update(lat_deg=91.0),
        r"^start\.lat_deg: must be <= 90",
    ),
    (
        "speed would go negative",
        lambda d: d["segments"][0].update(accel_m_s2=-20.0),
        r"^segments\[0\]\.accel_m_s2: speed would become negative",
    ),
    (
        "not a whole number of IMU periods",
        lambda d: d["segments"][0].update(duration_s=1.005),
        r"^segments\[0\]\.duration_s: must be a whole number of IMU periods",
    ),
    (
        "coordinated while rolling",
        lambda d: d["segments"][2].update(roll_rate_deg_s=1.0),
        r"^segments\[2\]\.yaw_rate_deg_s: a coordinated turn needs roll_rate_deg_s = 0",
    ),
    (
        "unknown key",
        lambda d: d["segments"][0].update(yaw_rate=1.0),
        r"^segments\[0\]\.yaw_rate: unknown key",
    ),
    ("NaN", lambda d: d["start"].update(h_m=float("nan")), r"^start\.h_m: is NaN or inf"),
    (
        "wrong yaw keyword",
        lambda d: d["segments"][2].update(yaw_rate_deg_s="coordinate"),
        r"^segments\[2\]\.yaw_rate_deg_s",
    ),
]


@pytest.mark.parametrize("label,change,pattern", CASES, ids=[c[0] for c in CASES])
def test_bad_profile_names_the_field(label, change, pattern):
    with pytest.raises(ScenarioError, match=pattern) as info:
        parse_profile(_bad(change))
    assert "\n" not in str(info.value)


def test_good_profile_parses():
    pr = parse_profile(GOOD)
    assert pr.duration == 35.0 and pr.segments[2].yaw_rate is None


def test_cli_rejects_bad_profile_with_status_2(tmp_path, capsys):
    f = tmp_path / "bad.toml"
    f.write_text(
        'name = "p"\n[start]\nlat_deg = 95.0\nlon_deg = 0.0\nh_m = 0.0\n'
        "[[segments]]\nduration_s = 1.0\n"
    )
    assert main(["trajectory", str(f), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("ftnav: error: start.lat_deg:") and "\n" not in err


def test_documented_profile_example_is_valid():
    """The profile example in docs/scenario-format.md parses (keeps the docs honest)."""
    import tomllib
    from pathlib import Path

    doc = Path(__file__).resolve().parents[2] / "docs" / "scenario-format.md"
    if not doc.exists():
        pytest.skip("docs not available")
    text = doc.read_text(encoding="utf-8").split("## Flight profiles")[1]
    example = text.split("```toml\n")[1].split("```")[0]
    pr = parse_profile(tomllib.loads(example))
    assert pr.name == "my-flight" and pr.segments[0].accel == 2.6
