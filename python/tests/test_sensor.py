"""One sensor's pipeline: bit for bit what `gelgrip reconstruct` and `gelgrip depth` write,
the real Mini presses in contact, colour order and strides, purity, read-only results,
and every bad input named."""

from __future__ import annotations

import json
from pathlib import Path
from typing import List

import numpy as np
import pytest

import gelgrip
from conftest import MINI, cli_json, figures, read_png, run_cli


def bits(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a).view(np.uint32)


def test_process_equals_gelgrip_reconstruct_bit_for_bit(
    mini_model: Path, mini_background: np.ndarray, mini_presses: List[Path], tmp_path: Path
) -> None:
    # Four presses at once: the CLI measures its noise thresholds on them, so the sensor
    # gets the same four as its noise frames.
    chosen = mini_presses[4:8]
    out = tmp_path / "rec"
    report = cli_json(
        "reconstruct",
        "--model",
        str(mini_model),
        "--background",
        str(MINI / "background.png"),
        "--out",
        str(out),
        "--json",
        *map(str, chosen),
    )
    frames = [read_png(p) for p in chosen]
    sensor = gelgrip.Sensor(gelgrip.Model.load(str(mini_model)), mini_background, noise_frames=frames)
    results = sensor.process_many(frames)
    assert len(report["images"]) == 4
    for path, r, listed in zip(chosen, results, report["images"]):
        depth = np.load(out / f"{path.stem}.depth.npy")
        gradients = np.load(out / f"{path.stem}.gradients.npy")
        assert r.depth_mm.dtype == np.float32 and r.depth_mm.shape == (480, 640)
        assert np.array_equal(bits(r.depth_mm), bits(depth)), path.name
        assert np.array_equal(bits(r.gradients), bits(gradients)), path.name
        assert figures(r) == {k: listed[k] for k in figures(r)}, path.name
        # One at a time gives the same as in parallel.
        assert np.array_equal(bits(sensor.process(frames[chosen.index(path)]).depth_mm), bits(depth))


def test_every_real_press_is_in_contact(
    mini_model: Path, mini_background: np.ndarray, mini_presses: List[Path]
) -> None:
    frames = np.stack([read_png(p) for p in mini_presses])
    sensor = gelgrip.Sensor(gelgrip.Model.load(str(mini_model)), mini_background, noise_frames=frames)
    results = sensor.process_many(frames)
    assert len(results) == 24
    for path, r in zip(mini_presses, results):
        assert r.in_contact, path.name
        assert r.area_mm2 > 0 and r.max_depth_mm > 0 and r.volume_mm3 > 0, path.name
        assert r.contact.dtype == np.bool_ and r.contact.any(), path.name
        assert r.centroid_px is not None
        assert float(r.depth_mm.max()) == pytest.approx(r.max_depth_mm, rel=1e-5)


def test_bgr_and_any_strides_give_the_same_bits(
    mini_model: Path, mini_background: np.ndarray, mini_presses: List[Path]
) -> None:
    model = gelgrip.Model.load(str(mini_model))
    frame = read_png(mini_presses[6])
    rgb = gelgrip.Sensor(model, mini_background, solver="dst", noise_frames=[frame])
    bgr = gelgrip.Sensor(
        model, mini_background[..., ::-1], solver="dst", color_order="bgr", noise_frames=[frame[..., ::-1]]
    )
    want = rgb.process(frame)
    # A reversed channel axis (negative strides), and a Fortran-ordered copy.
    got = bgr.process(frame[..., ::-1])
    assert np.array_equal(bits(want.depth_mm), bits(got.depth_mm))
    fortran = np.asfortranarray(frame)
    assert not fortran.flags.c_contiguous
    assert np.array_equal(bits(rgb.process(fortran).depth_mm), bits(want.depth_mm))
    # A view into a larger array (row and column strides not the image's).
    big = np.zeros((600, 800, 3), np.uint8)
    big[50:530, 70:710] = frame
    assert np.array_equal(bits(rgb.process(big[50:530, 70:710]).depth_mm), bits(want.depth_mm))


def test_process_is_pure_and_results_are_read_only(
    mini_model: Path, mini_background: np.ndarray, mini_presses: List[Path]
) -> None:
    sensor = gelgrip.Sensor(gelgrip.Model.load(str(mini_model)), mini_background)
    a, b = read_png(mini_presses[2]), read_png(mini_presses[17])
    first = sensor.process(a)
    sensor.process(b)
    again = sensor.process(a)
    assert np.array_equal(bits(first.depth_mm), bits(again.depth_mm))
    assert np.array_equal(first.contact, again.contact)
    for array in (first.depth_mm, first.gradients, first.contact):
        assert not array.flags.writeable
        with pytest.raises(ValueError):
            array[0, 0] = 1
    assert first.gradients.shape == (480, 640, 2)
    assert sensor.mm_per_px == pytest.approx(0.0317)


def test_poisson_equals_gelgrip_depth(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    g = rng.normal(0, 0.05, (40, 56, 2)).astype(np.float32)
    np.save(tmp_path / "g.npy", g)
    for solver in ("dst", "dct"):
        run_cli("depth", "--gradients", str(tmp_path / "g.npy"), "--out", str(tmp_path / f"{solver}.npy"), "--solver", solver)
        want = np.load(tmp_path / f"{solver}.npy")
        assert np.array_equal(bits(gelgrip.poisson(g, solver=solver)), bits(want)), solver
    # The default is `gelgrip depth`'s (dst), and float64 solves the same.
    assert np.array_equal(bits(gelgrip.poisson(g)), bits(np.load(tmp_path / "dst.npy")))
    assert np.array_equal(bits(gelgrip.poisson(g.astype(np.float64))), bits(np.load(tmp_path / "dst.npy")))


def test_bad_input_raises_naming_what_was_expected(
    mini_model: Path, mini_background: np.ndarray, mini_presses: List[Path], tmp_path: Path
) -> None:
    model = gelgrip.Model.load(str(mini_model))
    sensor = gelgrip.Sensor(model, mini_background)
    frame = read_png(mini_presses[0])
    with pytest.raises(ValueError, match="uint8"):
        sensor.process(frame.astype(np.float32))
    with pytest.raises(ValueError, match=r"\(H, W, 3\)"):
        sensor.process(frame[..., 0])
    with pytest.raises(ValueError, match=r"\(H, W, 3\)"):
        sensor.process(np.zeros((480, 640, 4), np.uint8))
    with pytest.raises(ValueError, match="640x480"):
        sensor.process(frame[:240, :320])
    with pytest.raises(gelgrip.DecodeError):
        sensor.process(b"\xff\xd8\xff\xe0 not a jpeg at all")
    with pytest.raises(TypeError, match="JPEG bytes"):
        sensor.process("press.png")
    with pytest.raises(gelgrip.DecodeError, match=r"frames\[1\]"):
        sensor.process_many([frame, b"\xff\xd8 broken"])
    with pytest.raises(FileNotFoundError, match="no such file"):
        gelgrip.Model.load(str(tmp_path / "missing.lut"))
    (tmp_path / "junk.lut").write_bytes(b"not a model")
    with pytest.raises(gelgrip.ModelError):
        gelgrip.Model.load(str(tmp_path / "junk.lut"))
    with pytest.raises(ValueError, match="background"):
        gelgrip.Sensor(model, mini_background[:100])
    with pytest.raises(ValueError, match="color_order"):
        gelgrip.Sensor(model, mini_background, color_order="rbg")
    with pytest.raises(ValueError, match="solver"):
        gelgrip.Sensor(model, mini_background, solver="fft")
    with pytest.raises(ValueError, match="float32 or float64"):
        gelgrip.poisson(np.zeros((8, 8, 2), np.int32))
    with pytest.raises(ValueError, match=r"\(H, W, 2\)"):
        gelgrip.poisson(np.zeros((8, 8, 3), np.float32))
    # Every gelgrip error is a GelgripError.
    assert issubclass(gelgrip.DecodeError, gelgrip.GelgripError)
    assert issubclass(gelgrip.ConfigError, gelgrip.GelgripError)
