"""Model files (ftnav.io.model_file): open ZIP+JSON+.npy format, never pickle; every
corrupted, edited or unsuitable file is refused with a one-line ModelFileError."""

from __future__ import annotations

import hashlib
import io
import json
import pickle
import zipfile

import numpy as np
import pytest

from ftnav.io.model_file import (
    ModelFile,
    ModelFileError,
    load_model,
    save_model,
    system_hash,
)

KIND = "rbf-detector"
SENSORS = ["gnss", "baro"]
HASH = system_hash({"q": np.eye(3) * 1e-4, "sensors": SENSORS})


def _arrays():
    rng = np.random.default_rng(7)
    return {
        "centres": rng.normal(size=(12, 5)),
        "widths": rng.uniform(0.5, 2.0, size=12).astype(np.float32),
        "weights": rng.normal(size=(12, 2)),
        "classes": np.arange(3, dtype=np.int64),
        "mask": np.array([True, False, True]),
        "scale": np.float64(2.5) * np.ones(()),
    }


def _save(path, kind=KIND, arrays=None, **settings):
    return save_model(
        path,
        kind,
        _arrays() if arrays is None else arrays,
        compatibility={"sensors": SENSORS, "states": 15, "system_hash": HASH},
        settings={"hidden": 12, "sigma": 0.75, "features": ("dz", "dz2"), **settings},
    )


def _members(path):
    with zipfile.ZipFile(path) as zf:
        return {name: zf.read(name) for name in zf.namelist()}


def _write_zip(path, members):
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, data in members.items():
            zf.writestr(name, data)


def _checksum(meta):
    body = {k: v for k, v in meta.items() if k != "checksum"}
    text = json.dumps(body, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


def _npy(array, allow_pickle=False):
    buf = io.BytesIO()
    np.lib.format.write_array(buf, array, allow_pickle=allow_pickle)
    return buf.getvalue()


def _rewrite(path, *, meta_change=None, reseal=True, members_change=None):
    """Rewrite the file: edit the metadata (optionally recomputing its checksum) and/or
    replace / add / remove (value None) members."""
    members = _members(path)
    meta = json.loads(members["metadata.json"])
    if meta_change is not None:
        meta_change(meta)
        if reseal:
            meta["checksum"] = _checksum(meta)
    members["metadata.json"] = json.dumps(meta).encode()
    for name, data in (members_change or {}).items():
        if data is None:
            members.pop(name)
        else:
            members[name] = data
    _write_zip(path, members)


def _error(path, **kwargs) -> str:
    with pytest.raises(ModelFileError) as info:
        load_model(path, **kwargs)
    msg = str(info.value)
    assert "\n" not in msg and "\r" not in msg
    assert msg.startswith(f"model {str(path)!r}: ")
    return msg


# --------------------------------------------------------------------------- round trip


def test_round_trip_bit_identical(tmp_path):
    path = _save(tmp_path / "det.npz")
    model = load_model(
        path, KIND, compatibility={"sensors": ("gnss", "baro"), "states": 15, "system_hash": HASH}
    )
    assert isinstance(model, ModelFile)
    assert model.kind == KIND and model.path == path
    want = _arrays()
    assert set(model.arrays) == set(want)
    for name, array in want.items():
        got = model.arrays[name]
        assert got.dtype == array.dtype and got.shape == array.shape
        assert got.tobytes() == array.tobytes()
        assert not got.flags.writeable
    with pytest.raises(TypeError):
        model.arrays["centres"] = np.zeros(1)  # type: ignore[index]
    with pytest.raises(ValueError):
        model.arrays["centres"][0, 0] = 1.0
    meta = model.metadata
    for key in (
        "format",
        "format_version",
        "kind",
        "ftnav_version",
        "created",
        "compatibility",
        "settings",
        "arrays",
        "checksum",
    ):
        assert key in meta
    assert meta["format"] == "ftnav-model" and meta["format_version"] == 1
    assert meta["created"].endswith("+00:00")
    assert model.settings == {"hidden": 12, "sigma": 0.75, "features": ["dz", "dz2"]}
    assert model.compatibility["system_hash"] == HASH
    assert meta["arrays"]["widths"] == {
        "dtype": "<f4",
        "shape": [12],
        "sha256": hashlib.sha256(want["widths"].tobytes()).hexdigest(),
    }
    # plain numpy opens it, without pickle
    with np.load(path, allow_pickle=False) as npz:
        assert set(want) <= set(npz.files)
        np.testing.assert_array_equal(npz["centres"], want["centres"])
        assert npz["classes"].dtype == np.int64
    with zipfile.ZipFile(path) as zf:
        assert all(i.compress_type == zipfile.ZIP_DEFLATED for i in zf.infolist())


def test_settings_numpy_values_become_plain_json(tmp_path):
    path = _save(
        tmp_path / "m.npz",
        mean=np.array([1.5, 2.0]),
        n=np.int32(4),
        flag=np.bool_(True),
        eps=np.float32(0.5),
    )
    settings = load_model(path).settings
    assert settings["mean"] == [1.5, 2.0] and settings["n"] == 4
    assert settings["flag"] is True and settings["eps"] == 0.5


def test_save_is_atomic_and_overwrites(tmp_path):
    path = _save(tmp_path / "m.npz")
    _save(path, kind="neuron-fusion")
    assert load_model(path).kind == "neuron-fusion"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.npz"]  # no temp file left


# --------------------------------------------------------------------------- corruption


@pytest.mark.parametrize("cut", ["empty", "first100", "half", "minus10", "minus1"])
def test_truncated_file(tmp_path, cut):
    path = _save(tmp_path / "m.npz")
    data = path.read_bytes()
    keep = {
        "empty": 0,
        "first100": 100,
        "half": len(data) // 2,
        "minus10": len(data) - 10,
        "minus1": len(data) - 1,
    }[cut]
    path.write_bytes(data[:keep])
    assert "truncated or not a ZIP archive" in _error(path)


def test_missing_file_and_folder(tmp_path):
    assert "file not found" in _error(tmp_path / "nope.npz")
    assert "folder" in _error(tmp_path)


def test_array_member_edited(tmp_path):
    path = _save(tmp_path / "m.npz")
    centres = _arrays()["centres"]
    centres[3, 1] += 1e-9
    _rewrite(path, members_change={"centres.npy": _npy(centres)})
    assert "array 'centres' was edited or corrupted (sha256 mismatch)" in _error(path)


def test_metadata_edited_keeps_old_checksum(tmp_path):
    path = _save(tmp_path / "m.npz")
    _rewrite(path, meta_change=lambda m: m["settings"].update(sigma=0.8), reseal=False)
    assert "metadata was edited or corrupted (checksum mismatch)" in _error(path)


def test_metadata_resealed_but_array_hash_still_checked(tmp_path):
    path = _save(tmp_path / "m.npz")
    weights = _arrays()["weights"] * 2.0
    _rewrite(
        path,
        meta_change=lambda m: m["settings"].update(sigma=0.8),
        members_change={"weights.npy": _npy(weights)},
    )
    assert "array 'weights' was edited or corrupted (sha256 mismatch)" in _error(path)


def test_array_dtype_or_shape_changed(tmp_path):
    path = _save(tmp_path / "m.npz")
    _rewrite(path, members_change={"widths.npy": _npy(_arrays()["widths"].astype(float))})
    assert "array 'widths' has dtype '<f8', the metadata says '<f4'" in _error(path)
    path = _save(tmp_path / "m.npz")
    _rewrite(path, members_change={"centres.npy": _npy(_arrays()["centres"].T)})
    assert "array 'centres' has shape [5, 12]" in _error(path)


def _member_data_span(path, member):
    data = path.read_bytes()
    with zipfile.ZipFile(path) as zf:
        info = zf.getinfo(member)
    start = info.header_offset
    name_len = int.from_bytes(data[start + 26 : start + 28], "little")
    extra_len = int.from_bytes(data[start + 28 : start + 30], "little")
    begin = start + 30 + name_len + extra_len
    return data, begin, begin + info.compress_size


@pytest.mark.parametrize("member", ["centres.npy", "metadata.json"])
def test_byte_flipped_inside_deflated_member(tmp_path, member):
    path = _save(tmp_path / "m.npz")
    want = _members(path)
    data, begin, end = _member_data_span(path, member)
    assert end - begin > 20
    detected = 0
    for pos in range(begin, end, max(1, (end - begin) // 40)):
        bad = bytearray(data)
        bad[pos] ^= 0x5A
        path.write_bytes(bytes(bad))
        try:
            load_model(path)
        except ModelFileError:
            msg = _error(path)
            assert "corrupted" in msg, msg
            detected += 1
        else:
            # a flip in deflate padding can leave the inflated bytes unchanged: harmless
            assert _members(path) == want
    assert detected > 0


def test_any_flipped_byte_is_detected_or_harmless(tmp_path):
    path = _save(tmp_path / "m.npz", arrays={"c": np.linspace(0.0, 1.0, 7)})
    data = path.read_bytes()
    want = load_model(path).arrays["c"].tobytes()
    for pos in range(len(data)):
        bad = bytearray(data)
        bad[pos] ^= 0xFF
        path.write_bytes(bytes(bad))
        try:
            model = load_model(path)
        except ModelFileError as exc:
            assert "\n" not in str(exc)
        else:  # e.g. a time stamp in a ZIP header: harmless
            assert model.arrays["c"].tobytes() == want


# --------------------------------------------------------------------------- contents


def test_wrong_kind(tmp_path):
    path = _save(tmp_path / "m.npz", kind="neuron-fusion")
    assert "is a 'neuron-fusion' model, expected 'rbf-detector'" in _error(path, kind=KIND)


def test_newer_format_version(tmp_path):
    path = _save(tmp_path / "m.npz")
    _rewrite(path, meta_change=lambda m: m.update(format_version=2))
    assert "format version 2 is newer than this ftnav supports (1)" in _error(path)


def test_not_an_ftnav_model(tmp_path):
    path = tmp_path / "plain.npz"
    np.savez_compressed(path, a=np.zeros(3))
    assert "has no metadata.json" in _error(path)
    _write_zip(path, {"metadata.json": b'{"format": "other"}'})
    assert "is not an ftnav model file" in _error(path)


def test_missing_metadata(tmp_path):
    path = _save(tmp_path / "m.npz")
    _rewrite(path, members_change={"metadata.json": None})
    assert "has no metadata.json" in _error(path)


@pytest.mark.parametrize(
    "text, reason",
    [
        (b"{not json", "metadata.json is not valid JSON"),
        (b'{"format": NaN}', "metadata.json is not valid JSON"),
        (b'{"a": 1, "a": 2}', "duplicate key 'a'"),
        (b"[1, 2]", "metadata.json is not a JSON object"),
        (b"\xff\xfe", "metadata.json is not UTF-8"),
    ],
)
def test_metadata_not_json_object(tmp_path, text, reason):
    path = _save(tmp_path / "m.npz")
    members = _members(path)
    members["metadata.json"] = text
    _write_zip(path, members)
    assert reason in _error(path)


def test_missing_and_extra_array(tmp_path):
    path = _save(tmp_path / "m.npz")
    _rewrite(path, members_change={"weights.npy": None})
    assert "array 'weights' is listed in the metadata but missing" in _error(path)
    path = _save(tmp_path / "m.npz")
    _rewrite(path, members_change={"bias.npy": _npy(np.zeros(2))})
    assert "array 'bias' is not listed in the metadata" in _error(path)
    path = _save(tmp_path / "m.npz")
    _rewrite(path, members_change={"run.py": b"print('hi')"})
    assert "unexpected member 'run.py'" in _error(path)


def test_nan_inside_array_with_consistent_hashes(tmp_path):
    path = _save(tmp_path / "m.npz")
    centres = _arrays()["centres"]
    centres[2, 2] = np.nan

    def change(meta):
        meta["arrays"]["centres"]["sha256"] = hashlib.sha256(centres.tobytes()).hexdigest()

    _rewrite(path, meta_change=change, members_change={"centres.npy": _npy(centres)})
    assert "array 'centres' contains NaN or inf" in _error(path)


def test_compatibility_mismatch(tmp_path):
    path = _save(tmp_path / "m.npz")
    msg = _error(path, compatibility={"sensors": ["gnss", "odo"]})
    assert "was trained for sensors = ['gnss', 'baro'], this scenario has ['gnss', 'odo']" in msg
    other = system_hash({"q": np.eye(3) * 2e-4, "sensors": SENSORS})
    msg = _error(path, compatibility={"states": 15, "system_hash": other})
    assert (
        f"was trained for another scenario (system hash {HASH[:12]}… differs from "
        f"{other[:12]}…)" in msg
    )
    assert "was trained without a recorded dt" in _error(path, compatibility={"dt": 0.01})
    # tuples equal lists, numpy ints equal ints, extra keys in the file are fine
    load_model(path, compatibility={"sensors": ("gnss", "baro"), "states": np.int64(15)})


def test_pickled_object_array_is_refused_without_unpickling(tmp_path, monkeypatch):
    path = _save(tmp_path / "m.npz")
    evil = np.array([{"x": 1}, None], dtype=object)
    blob = _npy(evil, allow_pickle=True)

    def change(meta):
        meta["arrays"]["payload"] = {
            "dtype": "|O",
            "shape": [2],
            "sha256": hashlib.sha256(b"").hexdigest(),
        }

    _rewrite(path, meta_change=change, members_change={"payload.npy": blob})

    def boom(*args, **kwargs):
        raise AssertionError("pickle was used")

    monkeypatch.setattr(pickle, "loads", boom)
    monkeypatch.setattr(pickle, "load", boom)
    msg = _error(path)
    assert "array 'payload' has dtype 'object', refused" in msg


# --------------------------------------------------------------------------- saving


@pytest.mark.parametrize(
    "bad, dtype",
    [
        (np.array([1, "a"], dtype=object), "object"),
        (np.array(["a", "b"]), "<U1"),
        (np.zeros(2, dtype=[("a", "f8"), ("b", "i4")]), "[('a', '<f8'), ('b', '<i4')]"),
    ],
)
def test_save_refuses_non_numeric_arrays(tmp_path, bad, dtype):
    with pytest.raises(ValueError, match=r"^arrays\.odd: dtype .* is not allowed"):
        _save(tmp_path / "m.npz", arrays={"ok": np.zeros(2), "odd": bad})
    assert not any(tmp_path.iterdir())


def test_save_refuses_nan_array(tmp_path):
    with pytest.raises(ValueError, match=r"^arrays\.w: contains NaN or inf"):
        _save(tmp_path / "m.npz", arrays={"w": np.array([1.0, np.inf])})


def test_save_refuses_bad_settings(tmp_path):
    with pytest.raises(ValueError, match=r"^settings\.norm\.scale\[1\]: nan is not allowed"):
        _save(tmp_path / "m.npz", norm={"scale": [1.0, float("nan")]})
    with pytest.raises(ValueError, match=r"^settings\.mean\[0\]: inf is not allowed"):
        _save(tmp_path / "m.npz", mean=np.array([np.inf]))
    with pytest.raises(ValueError, match=r"^settings\.fn: value of type function is not JSON"):
        _save(tmp_path / "m.npz", fn=lambda x: x)
    with pytest.raises(ValueError, match=r"^settings\.table: key 1 is not a string"):
        _save(tmp_path / "m.npz", table={1: "a"})
    with pytest.raises(ValueError, match=r"^compatibility\.sensors: value of type set"):
        save_model(tmp_path / "m.npz", KIND, {}, compatibility={"sensors": {"a"}}, settings={})
    assert not any(tmp_path.iterdir())


# --------------------------------------------------------------------------- helpers


def test_system_hash_deterministic_and_blind_to_the_last_bits_only():
    q = np.diag([1e-4, 2e-4, 3e-4])
    parts = {"q": q, "r": [0.5, 1.0], "sensors": ("gnss", "baro"), "dt": 0.01}
    h = system_hash(parts)
    assert len(h) == 64 and h == system_hash(dict(reversed(list(parts.items()))))
    assert h == system_hash({**parts, "q": q.copy(), "sensors": ["gnss", "baro"]})
    # a 1-ulp difference (another NumPy build's exp) keeps the hash ...
    q2 = q.copy()
    q2[1, 1] = np.nextafter(q2[1, 1], 1.0)
    assert system_hash({**parts, "q": q2}) == h
    assert system_hash({**parts, "dt": np.nextafter(0.01, 0.0)}) == h
    # ... a change in the 11th significant digit does not
    q3 = q.copy()
    q3[1, 1] *= 1.0 + 1e-10
    assert system_hash({**parts, "q": q3}) != h
    assert system_hash({**parts, "dt": 0.01 * (1.0 + 1e-10)}) != h
    with pytest.raises(ValueError, match=r"^q\[0\]\[0\]: nan"):
        system_hash({"q": np.full((1, 1), np.nan)})


def test_error_is_picklable():
    err = ModelFileError("dir/x.npz", "truncated or not a ZIP archive")
    assert str(err) == "model 'dir/x.npz': truncated or not a ZIP archive"
    back = pickle.loads(pickle.dumps(err))
    assert type(back) is ModelFileError and str(back) == str(err)
    assert back.path == err.path and back.reason == err.reason
    assert str(ModelFileError("x", "a\nb", field="settings.sigma")) == "settings.sigma: a b"
    assert isinstance(err, ValueError)
