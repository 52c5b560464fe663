"""Calibration from Python against the CLI: `label`, `train` and `evaluate` give the
`--json` objects `calibrate label|train|eval` print, and the trained model is the one
`calibrate train` writes."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Dict

import pytest

import gelgrip
from conftest import MINI, MINI_BALL_MM, MINI_MM_PER_PX, cli_json


def metadata(path: Path) -> Any:
    """A safetensors file's `__metadata__`."""
    data = path.read_bytes()
    n = int.from_bytes(data[:8], "little")
    return json.loads(data[8 : 8 + n])["__metadata__"]


def without(d: Dict[str, Any], *keys: str) -> Dict[str, Any]:
    return {k: v for k, v in d.items() if k not in keys}


def test_label_train_evaluate_match_the_cli(tmp_path: Path, mini_dataset: Path, mini_model: Path) -> None:
    cli_dir = tmp_path / "cli"
    want = cli_json(
        "calibrate", "label", "--in", str(MINI), "--out", str(cli_dir),
        "--ball-mm", str(MINI_BALL_MM), "--mm-per-px", str(MINI_MM_PER_PX), "--json",
    )
    got = gelgrip.label(str(MINI), str(tmp_path / "py"), MINI_BALL_MM, MINI_MM_PER_PX)
    assert got == want
    assert got["labelled"] == 24 and got["rejected"] == []
    assert (tmp_path / "py" / "presses.csv").read_text() == (cli_dir / "presses.csv").read_text()

    cli_model = tmp_path / "cli.lut"
    want = cli_json("calibrate", "train", "--data", str(mini_dataset), "--model", "lut", "--out", str(cli_model), "--json")
    model = gelgrip.train(str(mini_dataset), "lut")
    report = model.report
    assert report is not None
    assert without(report, "train_s") == without(want, "train_s")
    assert model.kind == "lut" and model.size == (640, 480)
    assert model.mm_per_px == pytest.approx(MINI_MM_PER_PX)
    saved = tmp_path / "py.lut"
    model.save(str(saved))
    # The same model as the CLI's file: its metadata (in another key order: the file's
    # JSON header comes from a hash map) and its tables, as an evaluation reads them.
    assert metadata(saved) == metadata(cli_model)
    assert gelgrip.evaluate(gelgrip.Model.load(str(saved)), str(mini_dataset), solver=None) == gelgrip.evaluate(
        gelgrip.Model.load(str(cli_model)), str(mini_dataset), solver=None
    )

    want = cli_json("calibrate", "eval", "--model", str(mini_model), "--data", str(mini_dataset), "--json")
    got = gelgrip.evaluate(gelgrip.Model.load(str(mini_model)), str(mini_dataset))
    assert got == want
    assert got["solver"] == "dst" and got["presses"] == 24
    none = gelgrip.evaluate(gelgrip.Model.load(str(mini_model)), str(mini_dataset), solver=None)
    assert none["solver"] == "none" and none["depth_mae_mm"] is None


def test_train_options_carry_the_cli_names_and_limits(mini_dataset: Path, tmp_path: Path) -> None:
    model = gelgrip.train(str(mini_dataset), "lut", bins=32, blur_px=1, input="relative")
    assert model.report is not None
    assert model.report["blur_px"] == 1 and model.report["input"] == "relative"
    assert model.input == "relative"
    with pytest.raises(ValueError, match="bins=1"):
        gelgrip.train(str(mini_dataset), "lut", bins=1)
    with pytest.raises(ValueError, match="model="):
        gelgrip.train(str(mini_dataset), "forest")
    with pytest.raises(ValueError, match="loss="):
        gelgrip.train(str(mini_dataset), "mlp", loss="l3")
    with pytest.raises(FileNotFoundError):
        gelgrip.train(str(tmp_path / "nothing"), "lut")
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(gelgrip.DataError):
        gelgrip.train(str(empty), "lut")
    with pytest.raises(gelgrip.ConfigError, match="ball_mm"):
        gelgrip.label(str(MINI), str(tmp_path / "x"), 0.0, MINI_MM_PER_PX)


def test_an_mlp_trains_with_its_validation_report(mini_dataset: Path, tmp_path: Path) -> None:
    model = gelgrip.train(str(mini_dataset), "mlp", epochs=2, hidden=8, seed=3)
    report = model.report
    assert report is not None and report["model"] == "mlp"
    assert report["validation"]["epochs"] == 2 and report["hidden"] == 8
    path = tmp_path / "m.mlp"
    model.save(str(path))
    assert gelgrip.Model.load(str(path)).kind == "mlp-contact"
