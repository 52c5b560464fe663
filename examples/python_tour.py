"""A notebook-sized tour of gelgrip from Python: label and train on the real GelSight Mini
presses, reconstruct them (one frame, then all at once), integrate gradients, look into a
recording, and grasp the simulated tennis ball.

Run from the repository after ``pip install ./python``::

    python examples/python_tour.py [--shared ../shared] [--work /tmp/gelgrip-tour]

It needs the repository's ``../shared/data/gelsight-mini-presses`` (or ``--shared``).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import List

import numpy as np

import gelgrip


def calibrate(presses: Path, work: Path) -> gelgrip.Model:
    """Label the presses (a 3.68 mm ball at 0.0317 mm/px) and train a LUT on them."""
    labelled = gelgrip.label(str(presses), str(work / "mini"), 3.68, 0.0317)
    print(f"labelled {labelled['labelled']} presses, camera noise {labelled['camera_noise']:.2f}")
    model = gelgrip.train(str(work / "mini"), model="lut")
    report = model.report
    assert report is not None
    print(f"trained {model.kind}: test MAE gx {report['test_gx_mae']:.3f} gy {report['test_gy_mae']:.3f}")
    model.save(str(work / "mini.lut"))
    scores = gelgrip.evaluate(gelgrip.Model.load(str(work / "mini.lut")), str(work / "mini"))
    print(f"sphere radius median {scores['sphere_radius_mm_median']:.3f} mm (ball {scores['ball_radius_mm']:.3f} mm)")
    return model


def reconstruct(model: gelgrip.Model, presses: Path) -> None:
    """One press, then all of them in parallel."""
    background = gelgrip.read_image(str(presses / "background.png"))
    frames: List[np.ndarray] = [gelgrip.read_image(str(p)) for p in sorted(presses.glob("press_*.png"))]
    sensor = gelgrip.Sensor(model, background, mm_per_px=None, solver="dct", color_order="rgb", noise_frames=frames)
    r = sensor.process(frames[6])
    print(
        f"press_006: contact {r.in_contact}, area {r.area_mm2:.1f} mm², max depth {r.max_depth_mm:.3f} mm, "
        f"volume {r.volume_mm3:.2f} mm³, centroid {r.centroid_px}"
    )
    print(f"  depth {r.depth_mm.shape} {r.depth_mm.dtype}, gradients {r.gradients.shape}, contact px {int(r.contact.sum())}")
    start = time.perf_counter()
    results = sensor.process_many(frames)
    took = time.perf_counter() - start
    print(f"{len(results)} presses in {took * 1e3:.0f} ms, all in contact: {all(x.in_contact for x in results)}")
    depth = gelgrip.poisson(r.gradients, solver="dct")
    print(f"full-frame DCT solve of press_006's gradients: peak {float(depth.max()):.2f} px")


def grasp(work: Path) -> None:
    """The simulated tennis ball, on the virtual clock."""
    with gelgrip.Gripper(config=None, clock="virtual", scene="tennis-ball") as g:
        s = g.next_set(timeout=30.0)
        print(f"first set at t={s.t_s:.3f} s, fingers {[f['phase'] for f in s.fingers]}")
        result = g.grasp(target_force_n=1.5)
        print(f"grasped: {result['grasped']} ({result['reason']}, {result['final_force_n']:.2f} N)")
        handle = g.start_grasp(target_force_n=1.0)
        print(f"regrasp at 1.0 N: grasped {handle.wait(timeout=60.0)['grasped']}")
        g.release()


def recording(path: Path) -> None:
    """A recording's summary and its first frame of sensor 0."""
    rec = gelgrip.Recording(str(path))
    info = rec.info()
    print(f"recording: {info['frames']} frames over {info['duration_s']:.2f} s from {info['transport']}")
    for frame in rec.frames(sensor=0):
        print(f"  {frame.sensor_id} at {frame.capture_us} µs: {frame.image().shape}")
        break


def main() -> None:
    ap = argparse.ArgumentParser()
    here = Path(__file__).resolve().parents[1]
    ap.add_argument("--shared", type=Path, default=here.parent / "shared")
    ap.add_argument("--work", type=Path, default=Path("/tmp/gelgrip-tour"))
    ap.add_argument("--recording", type=Path, default=None, help="a `gelgrip run --record` directory")
    a = ap.parse_args()
    a.work.mkdir(parents=True, exist_ok=True)
    presses = a.shared / "data" / "gelsight-mini-presses"
    model = calibrate(presses, a.work)
    reconstruct(model, presses)
    grasp(a.work)
    if a.recording is not None:
        recording(a.recording)


if __name__ == "__main__":
    main()
