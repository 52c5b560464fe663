"""Fixtures of the gelgrip package's tests: the real GelSight Mini presses (labelled and
a LUT trained on them, once per session), the gelgrip CLI to compare against, and
scratch directories.

The CLI is ``$GELGRIP_BIN`` (``scripts/test`` sets it to the test build's binary), else
``target/debug/gelgrip`` of the repository; the tests that compare against it are skipped
only when neither is set nor there.
"""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path
from typing import Any, Dict, List

import numpy as np
import pytest

import gelgrip

REPO = Path(__file__).resolve().parents[2]
MINI = REPO.parent / "shared" / "data" / "gelsight-mini-presses"
# The ball the realistic optics were fitted with, and gs_sdk's pixel size for the Mini
# (docs/calibration.md, "From presses to a metric depth map").
MINI_BALL_MM = 3.68
MINI_MM_PER_PX = 0.0317


def cli_path() -> Path:
    env = os.environ.get("GELGRIP_BIN")
    if env:
        path = Path(env)
        assert path.is_file(), f"GELGRIP_BIN={env}: no such file"
        return path
    path = REPO / "target" / "debug" / "gelgrip"
    if not path.is_file():
        pytest.skip("no gelgrip binary: set GELGRIP_BIN or build target/debug/gelgrip")
    return path


def run_cli(*args: str) -> subprocess.CompletedProcess[str]:
    """Run the gelgrip CLI; fail the test with its stderr when it fails."""
    out = subprocess.run(
        [str(cli_path()), *args],
        capture_output=True,
        text=True,
        env={**os.environ, "RUST_LOG": "warn"},
        timeout=600,
    )
    assert out.returncode == 0, f"gelgrip {' '.join(args)}: exit {out.returncode}\n{out.stderr}"
    return out


def cli_json(*args: str) -> Any:
    return json.loads(run_cli(*args).stdout)


def read_png(path: Path) -> np.ndarray:
    """A PNG as gelgrip reads it."""
    return np.asarray(gelgrip.read_image(str(path)))


@pytest.fixture(scope="session")
def mini_presses() -> List[Path]:
    presses = sorted(MINI.glob("press_*.png"))
    assert len(presses) == 24, f"{MINI}: expected the 24 Mini presses"
    return presses


@pytest.fixture(scope="session")
def mini_dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The Mini presses labelled by gelgrip.label."""
    out = tmp_path_factory.mktemp("mini") / "dataset"
    gelgrip.label(str(MINI), str(out), MINI_BALL_MM, MINI_MM_PER_PX)
    return out


@pytest.fixture(scope="session")
def mini_model(mini_dataset: Path) -> Path:
    """A LUT trained on the labelled Mini presses, saved."""
    path = mini_dataset.parent / "mini.lut"
    gelgrip.train(str(mini_dataset), "lut").save(str(path))
    return path


@pytest.fixture(scope="session")
def mini_background() -> np.ndarray:
    return read_png(MINI / "background.png")


def figures(r: gelgrip.Reconstruction) -> Dict[str, Any]:
    """A reconstruction's figures as `gelgrip reconstruct --json` names them."""
    return {
        "in_contact": r.in_contact,
        "area_mm2": r.area_mm2,
        "max_depth_mm": r.max_depth_mm,
        "volume_mm3": r.volume_mm3,
        "centroid_px": list(r.centroid_px) if r.centroid_px is not None else None,
    }
