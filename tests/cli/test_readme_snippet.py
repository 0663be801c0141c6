"""The README's Python snippet runs as written, for a linear and an integrated scenario.

The snippet is read from README.md itself; only the file name and the number of runs
are replaced (a copy of a built-in, shortened so the test is quick).
"""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import numpy as np
import pytest
import tomli_w

from ftnav.scenarios import builtin_path

README = (Path(__file__).parents[2] / "README.md").read_text()


def _snippet() -> str:
    blocks = re.findall(r"```python\n(.*?)```", README, flags=re.S)
    code = next(b for b in blocks if "load_scenario(" in b and "evaluate(" in b)
    assert '"my_model.toml"' in code and "runs=200" in code
    return code


def _engine_snippet() -> str:
    blocks = re.findall(r"```python\n(.*?)```", README, flags=re.S)
    return next(b for b in blocks if "navigation_model(" in b)


def _copy(name: str, tmp_path: Path, steps: int) -> Path:
    data = tomllib.loads(builtin_path(name).read_text())
    if data.get("kind") == "integrated":
        data["filter"]["duration_s"] = float(steps)
        data["faults"] = [f for f in data["faults"] if f["start"] < steps]
        data["profile"] = str(builtin_path(name).parent / "profiles" / f"{data['profile']}.toml")
        data.pop("test_profile", None)
    else:
        data["steps"] = steps
        data["faults"] = [f for f in data["faults"] if f["start"] < steps * data["dt"]]
    data["methods"] = [m for m in data["methods"] if m["architecture"] == "centralized"][:1] + [
        m for m in data["methods"] if m["architecture"] == "distributed"
    ][:1]
    data.pop("figures", None)
    path = tmp_path / "my_model.toml"
    path.write_text(tomli_w.dumps(data))
    return path


@pytest.mark.parametrize(("name", "steps"), [("seed000", 200), ("seed002", 120)])
def test_readme_python_snippet(name, steps, tmp_path, monkeypatch, capsys):
    path = _copy(name, tmp_path, steps)
    code = _snippet().replace('"my_model.toml"', repr(str(path))).replace("runs=200", "runs=3")
    scope: dict = {}
    exec(compile(code, "README.md", "exec"), scope)  # the snippet as a user runs it
    metrics, sc = scope["metrics"], scope["sc"]
    assert set(metrics) == {m.name for m in sc.methods}
    ckf = metrics["ckf"]
    assert set(ckf.rmse) >= set(sc.metric_states)
    assert all(v > 0 for v in ckf.rmse.values())
    assert str(ckf.rmse)[:20] in capsys.readouterr().out
    frame = scope["frame"]
    assert list(frame.index) == list(metrics) and frame.loc["ckf", "anees"] == ckf.anees
    exec(compile(_engine_snippet(), "README.md", "exec"), scope)  # the engine, after it
    x = scope["traces"]["ckf"].x
    assert x.shape[:2] == (3, sc.steps) and np.isfinite(x).all()


def _recording_snippet() -> str:
    blocks = re.findall(r"```python\n(.*?)```", README, flags=re.S)
    return next(b for b in blocks if "process_recording(" in b)


def test_readme_recording_snippet(tmp_path, capsys):
    """The README's one-call route on a short copy of the drive (60 s, GNSS only): a
    DataFrame of the solution and of the smoothed one, and the scores."""
    from recording_runs import drive_copy

    def short(doc: dict) -> None:
        doc["aids"] = [a for a in doc["aids"] if a["type"] == "gnss"]
        doc["filter"] = {**doc.get("filter", {}), "duration_s": 90.0}

    path = drive_copy(tmp_path / "drive.toml", short)
    code = _recording_snippet().replace('"rtklib-drive"', repr(str(path)))
    code = code.replace("outages=(15, 60, 40)", "outages=(10, 30, 20)")
    scope: dict = {}
    exec(compile(code, "README.md", "exec"), scope)
    df, smoothed, result = scope["df"], scope["smoothed"], scope["result"]
    assert scope["err"].shape == (len(result.reference.index), 3)
    assert list(df.columns[:4]) == ["method", "time_s", "lat_deg", "lon_deg"]
    assert set(df["method"]) == {"ckf"} and len(df) == result.recording.steps
    assert np.isfinite(df.drop(columns="method").to_numpy()).all()
    assert smoothed.shape == df.shape
    s = result.scores["ckf"]
    assert 0 < s.horizontal_rms_m < 0.5 and s.outages.count >= 2
    assert scope["drift"] is s.outages and s.as_dict()["outages"]["count"] == s.outages.count
    assert "ckf" in capsys.readouterr().out
