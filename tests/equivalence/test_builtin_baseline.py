"""The built-in scenarios give the numbers recorded before the redesign (issues 13-14).

``tests/data/builtin_baseline.json`` holds the ``methods`` section of ``metrics.json``
(and of its ``second_trajectory``) of ``ftnav run <built-in> --runs 2 --seed 1``,
recorded from commit 3648194 plus the model-hash fix, before any change of defaults or
structure.  Every recorded number must come back to 1e-9 relative; keys may be added
to ``metrics.json`` but none recorded may disappear.  Record again only for a change
that is meant to change results, and say so in the commit.

Recorded again for issue 20 (the guard under every detector): only methods with a
detector changed — seed000 ``fkf-inverse-trace-chi2``, ``-chi2-local-prior``, ``-rbf``,
``dkf-chi2``, ``dkf-chi2-local-prior``, ``neural-chi2``; seed001 ``fkf-nr-chi2``,
``fkf-nr-chi2-keep``, ``neural-chi2-feedback``; seed002 ``fkf-chi2``.  Why: an aid is
re-admitted by the guard's own n_off passes and used from the next epoch (recoveries one
epoch later: 4 → 5 s), a newly isolated aid's pull is rolled back, and false alarms and
ANEES move with that (seed002 ``fkf-chi2`` ANEES 9.85 → 11.90; seed001 ``fkf-nr-chi2``
1912 → 1902).  Every method without a detector is unchanged to 1e-9.

Recorded again for issue 22 (``eval.navigation.metric_scale`` added the height twice to
the Earth radii): only the position errors in metres changed, each by h/R — seed001 by
2.0e-4 relative (e.g. ``ckf`` second trajectory ``max_abs_error.pos_N_m`` 46.503 → 46.493),
seed002 by up to 4.6e-4 (``ckf`` ``max_abs_error.pos_horizontal_m`` 5.6774 → 5.6748);
seed000 (linear) and every non-metric number unchanged to 1e-9.

Recorded again for issue 20 (the patience beside aids that cannot judge the jump,
``Guard._unwitnessed``): only seed002 ``dkf-vb-chi2`` changed, a hold under the GNSS
noise anomalies now ended by the patience where the star tracker and altimeter see none
of the jumped rows (horizontal RMSE 1.2300 → 1.2413 m, ANEES 9.196 → 9.145, GNSS
detection rate 0.0997 → 0.0994); every other method of every built-in unchanged to 1e-9.

Recorded again for issue 20 (a doubtful rollback deferred while the flagged fix agrees
with the estimate, docs/integrity.md §1.11): only seed002 ``dkf-vb-chi2`` changed (57
numbers; horizontal RMSE 1.2349 → 1.2057 m, ANEES 9.181 → 9.012, NEES in band 0.876 →
0.882, GNSS detection rate 0.1039 → 0.1031); every other method of every built-in
unchanged to 1e-9.

Recorded again for issue 20 (a held aid beside others whose increments show a noise far
above its R passes only the strict test, not the coasting allowance): only seed002
``fkf-chi2`` and ``fkf-cusum`` changed, under the GNSS noise anomalies (horizontal RMSE
58.65 → 49.33 m and 54.80 → 42.92 m, ANEES 11.90 → 10.75 and 11.28 → 9.29, the CUSUM's
false alarms 6.1 → 0 per hour on the GNSS); every other method unchanged to 1e-9.

Recorded again for issue 20 (independent locals: two held aids of different devices
back each other across the no-reset federated locals, and a relaxed re-admission
restarts the local from the fused reference with its common covariance over its
share): only seed001 ``fkf-nr-chi2``, ``fkf-nr-glr`` and ``fkf-nr-chi2-keep`` changed,
under the SINS gyro fault (horizontal RMSE 122.5 → 19.4, 118.8 → 20.5 and 20.1 → 19.2
m; second flight 132.9 → 18.0, 123.6 → 22.3 and 13.6 → 22.5 m; ``ckf`` 21.3 and
23.6 m), their fault-free twins unchanged; every other method unchanged to 1e-9.

Recorded again for issue 20 (a held aid beside others whose increments show a noise past
16 times its R is not re-admitted while they show it; a milder show needs a consistent
increment with each strict pass): only seed002 ``fkf-chi2``, ``fkf-cusum`` and
``dkf-vb-chi2`` changed, under the GNSS noise anomalies (horizontal RMSE 49.33 → 44.42,
42.92 → 43.11 and 1.241 → 1.243 m; ANEES 10.75 → 9.37 and 9.29 → 9.56; the GNSS's mean
recovery 4.75 → 9.75 and 10.0 s: re-admitted once the noise window clears); every other
method unchanged to 1e-9.

Recorded again for issue 20 (the same noise rule for independent locals, their
increments judged against R and their private states' part): only seed001
``fkf-nr-chi2``, ``fkf-nr-glr`` and ``fkf-nr-chi2-keep`` changed, under the SINS gyro
fault (horizontal RMSE 19.39 → 19.29, 20.51 → 19.21, 19.22 → 17.58 m; second flight
17.97 → 25.17, 22.29 → 23.64, 22.53 → 20.65 m; ``ckf`` 21.3 and 23.6 m), fault-free
twins unchanged; every other method unchanged to 1e-9.

Recorded again for issue 20 (a held aid beside others is used with the noise its
increments show in the rows no other aid responds to): only seed002 ``fkf-chi2``,
``fkf-cusum`` and ``dkf-vb-chi2`` changed, under the GNSS noise anomalies, whose
horizontal rows the star tracker and altimeter do not see (horizontal RMSE 44.42 → 1.339,
43.11 → 1.336 and 1.243 → 1.235 m, ``ckf`` 1.397 m; ANEES 9.37 → 10.71, 9.56 → 10.50;
their fault-free twins by under 1e-3 relative); every other method unchanged to 1e-9.

Recorded again for issue 20 (independent locals keep their jump sums, and an aid's jump
back that undoes the one it was re-admitted with comes home at once): only seed001
``fkf-nr-chi2-keep``'s second flight changed (horizontal RMSE 20.65 → 21.44 m, ``ckf``
23.6 m); every other method unchanged to 1e-9.

Recorded again for issue 20 (a held VB local learns only a noise the guard sees, a local
let back in restarts from the centre, and a home needs the kept jump sum to be a jump
beyond chance: docs/integrity.md §1.12): only seed002 ``dkf-vb-chi2`` changed (89
numbers; horizontal RMSE 1.2057 → 1.2047 m, its largest error 10.17 → 4.49 m — the home
on a pile of noisy increments under the noise ramp —, ANEES 9.012 → 9.146, NEES in band
0.882 → 0.876, GNSS detection rate 0.1031 → 0.1169; fault-free twin 0.4833 → 0.4828 m);
every other method of every built-in unchanged to 1e-9.

Recorded again for issue 20 (a held VB local learns as before where its hold keeps no
jump, docs/integrity.md §1.12: learning only a noise the guard saw had held the real
drive's GNSS 6.9 % of the time): only seed002 ``dkf-vb-chi2`` changed, by under 1e-4
relative but its fault-free twin (horizontal RMSE 1.20470 → 1.20471 m, ANEES 9.146 →
9.144; fault-free twin 0.48285 → 0.48305 m, ANEES 9.300 → 9.268); every other method
unchanged to 1e-9.

Recorded again for issue 20 (an independent local let back in far from the reference its
aid passed against restarts from it, docs/integrity.md §1.14): seed000 ``neural-chi2``
(position RMSE 1.698 → 1.700) and seed001's neural and no-reset federated methods with a
detector changed (horizontal RMSE ``neural-chi2`` 386.5 → 316.8 m, its fault-free twin
322.0 → 243.4 m; ``neural-chi2-converged`` 114.2 → 118.0 m; ``fkf-nr-chi2`` 19.29 →
18.82 m; second flight ``fkf-nr-chi2-keep`` 21.44 → 26.24 m, inside the SINS fault that
lasts to the end, 27.34 m once a local re-admitted relaxed is fused at once); the
federated methods' fault-free twins, seed001's feedback neural method and every seed002
number unchanged to 1e-9.

Recorded again for issue 20 (a VB local takes its measurement with its predicted noise,
learning nothing, while another aid that measures is held, docs/integrity.md §1.15):
only seed002 ``dkf-vb-chi2`` changed (89 numbers; horizontal RMSE 1.2047 → 1.2118 m,
ANEES 9.144 → 9.152, GNSS detection rate 0.1169 → 0.1175; fault-free twin 0.48305 →
0.48294 m); every other method of every built-in unchanged to 1e-9.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from ftnav.cli import main

BASELINE = json.loads((Path(__file__).parents[1] / "data" / "builtin_baseline.json").read_text())
RTOL = 1e-9


def _compare(expected, actual, path: str, bad: list[str]) -> None:
    if isinstance(expected, dict):
        if not isinstance(actual, dict):
            bad.append(f"{path}: expected a table, got {actual!r}")
            return
        for key, value in expected.items():
            if key not in actual:
                bad.append(f"{path}.{key}: missing")
            else:
                _compare(value, actual[key], f"{path}.{key}", bad)
    elif isinstance(expected, list):
        if not isinstance(actual, list) or len(actual) != len(expected):
            bad.append(f"{path}: expected {len(expected)} values, got {actual!r}")
            return
        for i, (e, a) in enumerate(zip(expected, actual, strict=True)):
            _compare(e, a, f"{path}[{i}]", bad)
    elif isinstance(expected, bool) or expected is None or isinstance(expected, str):
        if actual != expected:
            bad.append(f"{path}: {actual!r} != {expected!r}")
    elif isinstance(expected, int | float):
        if (
            not isinstance(actual, int | float)
            or isinstance(actual, bool)
            or not math.isclose(actual, expected, rel_tol=RTOL, abs_tol=1e-300)
        ):
            bad.append(f"{path}: {actual!r} != {expected!r}")


@pytest.mark.parametrize("name", sorted(BASELINE))
def test_builtin_metrics_are_unchanged(name, tmp_path, capsys):
    expected = BASELINE[name]
    out = tmp_path / name
    assert (
        main(
            [
                "run",
                name,
                "--runs",
                str(expected["runs"]),
                "--seed",
                str(expected["seed"]),
                "--no-figures",
                "--quiet",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    capsys.readouterr()
    actual = json.loads((out / "metrics.json").read_text())
    bad: list[str] = []
    _compare(expected["methods"], actual["methods"], "methods", bad)
    if "second_trajectory" in expected:
        _compare(
            expected["second_trajectory"]["methods"],
            actual["second_trajectory"]["methods"],
            "second_trajectory.methods",
            bad,
        )
    assert not bad, f"{len(bad)} numbers changed, first: " + "; ".join(bad[:5])
