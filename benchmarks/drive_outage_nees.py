"""Is the drive's outage covariance honest?  End-of-outage NEES of ``ckf`` (issue 20).

The vendored rtklibexplorer car drive (``rtklib-drive``), the centralized filter, GNSS
outages on several schedules, with every aid of the file (GNSS positions and
velocities, NHC, ZUPT) and with the GNSS positions alone (``--aids gnss``).  Printed per
case: the mean over the outages of the 2-dof NEES of the horizontal error at each
outage's last withheld fix (at the antenna, against the fix; the covariance is the
filter's horizontal position block, E and N with their correlation, plus the fix's own
noise), the two-sided 95 % band of that mean (``χ²(2n)/n``, n outages), the largest
single NEES, the RMS over outages of the maximum horizontal drift, and the GNSS-on
horizontal RMS (posterior at the fix, as ``ftnav process`` scores it).

``--variants`` also runs the file with other accelerometer error models, written to a
temporary copy of the recording file (nothing else changed): what an honest outage
covariance with GNSS alone would cost the other cases.  They were measured to locate the
cause of the GNSS-alone NEES (an along-track error, docs/integrity.md §5), not to tune the
file: the file keeps its own model.

    python benchmarks/drive_outage_nees.py              # the file as it is
    python benchmarks/drive_outage_nees.py --variants   # and the alternative models
"""

from __future__ import annotations

import argparse
import re
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.stats import chi2

from ftnav.engine import navigation_model
from ftnav.engine.driver import run
from ftnav.eval.metrics import nees
from ftnav.eval.montecarlo import build_filters
from ftnav.eval.recorded import reference_errors, score_recording
from ftnav.io.recording_file import load_recording
from ftnav.nav.earth import radii
from ftnav.pipeline import reference_of
from ftnav.recordings import recording_path

#: (name, aids or None for every aid, (length, every, start) s)
CASES = [
    ("every aid, 15 s / 60 s", None, (15.0, 60.0, 40.0)),
    ("every aid, 30 s / 90 s", None, (30.0, 90.0, 40.0)),
    ("GNSS positions alone, 15 s / 60 s", ["gnss"], (15.0, 60.0, 40.0)),
    ("GNSS positions alone, 30 s / 90 s", ["gnss"], (30.0, 90.0, 40.0)),
    ("GNSS receiver alone, 10 s / 45 s", ["gnss", "gnss-vel"], (10.0, 45.0, 40.0)),
]

#: (name, {key of [imu.errors] or [filter]: value}) written over the file's own lines
VARIANTS: list[tuple[str, dict[str, str]]] = [
    (
        "accelerometer Markov 10 mg, 60 s",
        {"accel_markov_sd": '"10 mg"', "accel_markov_tau": '"60 s"'},
    ),
    (
        "accelerometer Markov 10 mg, 20 s",
        {"accel_markov_sd": '"10 mg"', "accel_markov_tau": '"20 s"'},
    ),
    ("18 states (Markov accelerometer bias)", {"states": "18"}),
]


def end_of_outage_nees(
    path: Path, aids: list[str] | None, outage: tuple[float, float, float]
) -> tuple[np.ndarray, float, float]:
    """Per outage the 2-dof NEES at its last withheld fix; the RMS of the maximum drift
    and the GNSS-on horizontal RMS (m)."""
    loaded = load_recording(path, outage=outage, methods=["ckf"], aids=aids, warn=False)
    rec = loaded.recording
    filters = build_filters(rec, rec.system(), rec.methods)
    tr = run(navigation_model(rec), loaded.stream, filters, rec.steps, nav_covariance=True)["ckf"]
    assert tr.solution is not None and tr.P_nav is not None
    ref = reference_of(loaded)
    R_fix = rec.system().sensors[0].R[:2, :2]  # the fix's own noise (m²)
    idx = loaded.reference_index
    t = rec.times[idx]
    out = []
    for g, outages in enumerate(loaded.outages):
        err = reference_errors(tr.solution, ref, g)[:, :2]
        for a, b in outages:
            inside = np.flatnonzero((t >= a) & (t < b))
            if inside.size == 0:
                continue
            k = inside[-1]
            p = tr.solution.p[g, idx[k]]
            R_Mh, R_Nh = radii(p[0], p[2])
            T = np.array([[0.0, R_Nh * np.cos(p[0])], [R_Mh, 0.0]])  # (E, N) m from (δL, δλ)
            S = T @ tr.P_nav[g, idx[k], 6:8, 6:8] @ T.T + R_fix
            out.append(float(nees(err[k][None], S[None])[0]))
    scores = score_recording(rec, {"ckf": tr}, ref, loaded.outages)["ckf"]
    assert scores.outages is not None and scores.horizontal_rms_m is not None
    return np.array(out), scores.outages.rms_max_error_m, scores.horizontal_rms_m


def variant_file(folder: Path, changes: dict[str, str]) -> Path:
    """A copy of the built-in drive's file with ``changes`` written over its lines, its
    data folder linked beside it."""
    source = recording_path("rtklib-drive")
    text = source.read_text()
    for key, value in changes.items():
        text, n = re.subn(rf"(?m)^{key} = .*$", f"{key} = {value}", text)
        assert n == 1, key
    (folder / "data").symlink_to(source.parent / "data")
    path = folder / "rtklib-drive.toml"
    path.write_text(text)
    return path


def table(name: str, path: Path) -> None:
    print(f"\n## {name}\n")
    print("| case | mean NEES at the outage's end (band) | largest | drift RMS m | GNSS on m |")
    print("|---|---|---|---|---|")
    for case, aids, outage in CASES:
        t0 = time.perf_counter()
        each, drift, on = end_of_outage_nees(path, aids, outage)
        n = each.size
        lo, hi = chi2.ppf([0.025, 0.975], 2 * n) / n
        verdict = "inside" if lo <= each.mean() <= hi else "**outside**"
        print(
            f"| {case} | {each.mean():.2f} [{lo:.2f}, {hi:.2f}] {verdict} ({n} outages) | "
            f"{each.max():.1f} | {drift:.2f} | {on:.3f} |"
            f"<!-- {time.perf_counter() - t0:.0f} s -->",
            flush=True,
        )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variants", action="store_true", help="also the alternative models")
    a = ap.parse_args()
    table("the file as it is", recording_path("rtklib-drive"))
    if a.variants:
        for name, changes in VARIANTS:
            with tempfile.TemporaryDirectory() as d:
                table(name, variant_file(Path(d), changes))


if __name__ == "__main__":
    main()
