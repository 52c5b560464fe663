"""Recordings from Python against `record info --json`, and their frames."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import gelgrip
from conftest import cli_json, run_cli


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("rec") / "run"
    run_cli("run", "--headless", "--clock", "virtual", "--duration", "0.5", "--record", str(out))
    return out


def test_info_equals_record_info_json(recording: Path) -> None:
    rec = gelgrip.Recording(str(recording))
    assert rec.info() == cli_json("record", "info", str(recording), "--json")
    assert rec.sensors == rec.info()["sensors"] and len(rec.sensors) == 7


def test_frames_by_sensor_with_their_images(recording: Path) -> None:
    rec = gelgrip.Recording(str(recording))
    frames = list(rec.frames())
    assert len(frames) == rec.info()["frames"] > 0
    times = [f.capture_us for f in frames if f.sensor == 0]
    first = list(rec.frames(sensor=0))
    assert [f.capture_us for f in first] == times
    by_id = list(rec.frames(sensor=rec.sensors[0]))
    assert [f.trigger_seq for f in by_id] == [f.trigger_seq for f in first]
    f = first[0]
    assert f.sensor_id == rec.sensors[0]
    assert f.jpeg[:2] == b"\xff\xd8"
    image = f.image()
    assert image.dtype == np.uint8 and image.ndim == 3 and image.shape[2] == 3
    assert not image.flags.writeable
    assert np.array_equal(f.image(color_order="bgr"), image[..., ::-1])
    with pytest.raises(KeyError):
        rec.frames(sensor=99)
    with pytest.raises(KeyError):
        rec.frames(sensor="no.such.sensor")


def test_bad_recordings(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError):
        gelgrip.Recording(str(tmp_path / "missing"))
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(gelgrip.RecordingError):
        gelgrip.Recording(str(empty))
