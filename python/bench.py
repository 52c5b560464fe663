#!/usr/bin/env python3
"""The gelgrip package's acceptance figures, measured in one run (docs/python.md):

1. ``process_many`` on one set of seven 320x240 JPEG frames of 6 mm-ball presses
   (simulated f1.tip presses from ``gelgrip calibrate collect``, a LUT trained on them with
   ``gelgrip.train``), against ``../shared/reference/python_pipeline.py``'s median ms per
   set (numpy, OpenCV, SciPy: 7 sensors, 320x240, LUT + DST), run in the same session;
2. the GIL: a pure-Python counting thread's pace alone, then while another thread calls
   ``Sensor.process`` in a loop;
3. ``Sensor.process`` on one real 640x480 GelSight Mini press against the same steps in
   numpy and SciPy (a 64^3 table lookup of the difference image, a full-frame DCT Poisson
   solve);
4. the process's resident memory over 100 000 ``process`` calls.

Needs a release build of the package (``pip install ./python``), numpy, SciPy and
opencv-python-headless (for the reference pipeline) in the same venv, and the gelgrip CLI
(``--cli``, default ``target/release/gelgrip``) for the simulated presses. Prints one JSON
object; ``--calls`` and ``--sets`` shorten a trial run.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any, Callable, Dict, List

import numpy as np

# The installed (release) package, never the source folder beside this script, which holds
# `maturin develop`'s debug build when there is one.
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]
import gelgrip  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared"


def median_ms(fn: Callable[[], object], runs: int) -> float:
    fn()
    times = []
    for _ in range(runs):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return 1e3 * float(np.median(times))


def rss_mb() -> float:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


def simulated_set(cli: Path, work: Path) -> tuple[gelgrip.Sensor, List[bytes]]:
    """Seven JPEG frames (quality 90, as the reference encodes) of f1.tip's 6 mm presses and
    a sensor with a LUT trained on the presses."""
    import cv2

    data = work / "f1.tip"
    subprocess.run(
        [str(cli), "calibrate", "collect", "--sensor", "f1.tip", "--presses", "20", "--out", str(data)],
        check=True,
        capture_output=True,
    )
    model = gelgrip.train(str(data), "lut")
    background = gelgrip.read_image(str(data / "background.png"))
    presses = sorted(p for p in data.glob("*.png") if p.name not in ("background.png",))[:7]
    jpegs = []
    for p in presses:
        bgr = np.ascontiguousarray(gelgrip.read_image(str(p), color_order="bgr"))
        ok, buf = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, 90])
        assert ok
        jpegs.append(buf.tobytes())
    sensor = gelgrip.Sensor(model, background, noise_frames=jpegs)
    return sensor, jpegs


def reference_ms(sets: int) -> Dict[str, Any]:
    out = subprocess.run(
        [sys.executable, str(SHARED / "reference" / "python_pipeline.py"), "--sets", str(sets)],
        check=True,
        capture_output=True,
        text=True,
    )
    result: Dict[str, Any] = json.loads(out.stdout)
    return result


def gil_share(sensor: gelgrip.Sensor, frame: bytes, seconds: float) -> Dict[str, float]:
    """Counts per second of a pure-Python loop, alone and beside a `process` loop."""

    def count(stop: threading.Event, out: List[int]) -> None:
        n = 0
        while not stop.is_set():
            n += 1
        out.append(n)

    def pace(with_worker: bool) -> float:
        stop, out = threading.Event(), []  # type: ignore[var-annotated]
        calls = [0]

        def work() -> None:
            while not stop.is_set():
                sensor.process(frame)
                calls[0] += 1

        threads = [threading.Thread(target=count, args=(stop, out))]
        if with_worker:
            threads.append(threading.Thread(target=work))
        for t in threads:
            t.start()
        time.sleep(seconds)
        stop.set()
        for t in threads:
            t.join()
        if with_worker:
            print(f"  process calls beside the counter: {calls[0] / seconds:.0f}/s", file=sys.stderr)
        return out[0] / seconds

    solo = pace(False)
    beside = pace(True)
    return {"solo_counts_per_s": solo, "beside_process_counts_per_s": beside, "share": beside / solo}


def numpy_scipy_ms(frame: np.ndarray, background: np.ndarray, runs: int) -> float:
    """A 64^3 table lookup of the difference image and a full-frame DCT Poisson solve."""
    from scipy.fft import dctn, idctn

    rng = np.random.default_rng(0)
    bins = 64
    lut_x = rng.normal(0, 0.1, bins**3).astype(np.float32)
    lut_y = rng.normal(0, 0.1, bins**3).astype(np.float32)
    ref = background.astype(np.float32)
    h, w = frame.shape[:2]
    ky, kx = np.meshgrid(np.arange(h), np.arange(w), indexing="ij")
    denom = (2 * np.cos(np.pi * kx / w) - 2) + (2 * np.cos(np.pi * ky / h) - 2)
    denom[0, 0] = 1.0

    def steps() -> None:
        diff = frame.astype(np.float32) - ref
        q = np.clip(((diff + 256) * bins / 512).astype(np.int32), 0, bins - 1)
        k = (q[..., 0] * bins + q[..., 1]) * bins + q[..., 2]
        gx, gy = lut_x[k], lut_y[k]
        div = np.zeros_like(gx)
        div[:, 1:] += gx[:, 1:] - gx[:, :-1]
        div[1:, :] += gy[1:, :] - gy[:-1, :]
        f = dctn(div, type=2, norm="ortho") / denom
        f[0, 0] = 0.0
        depth = idctn(f, type=2, norm="ortho")
        _ = (depth > 0.05).sum(), depth.max()

    return median_ms(steps, runs)


def memory(sensor: gelgrip.Sensor, frame: bytes, calls: int) -> Dict[str, float]:
    for _ in range(1000):
        sensor.process(frame)
    before = rss_mb()
    t = time.perf_counter()
    for _ in range(calls):
        sensor.process(frame)
    return {
        "calls": calls,
        "rss_before_mb": before,
        "rss_after_mb": rss_mb(),
        "growth_mb": rss_mb() - before,
        "seconds": time.perf_counter() - t,
    }


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--cli", type=Path, default=REPO / "target" / "release" / "gelgrip")
    ap.add_argument("--sets", type=int, default=40, help="the reference pipeline's sets")
    ap.add_argument("--runs", type=int, default=50, help="timed runs of each median")
    ap.add_argument("--gil-seconds", type=float, default=3.0)
    ap.add_argument("--calls", type=int, default=100_000, help="process calls of the memory check")
    a = ap.parse_args()
    report: Dict[str, Any] = {
        "gelgrip": gelgrip.__version__,
        "gelgrip_file": gelgrip.__file__,
        "numpy": np.__version__,
    }
    with tempfile.TemporaryDirectory() as tmp:
        sensor, jpegs = simulated_set(a.cli, Path(tmp))
    many = median_ms(lambda: sensor.process_many(jpegs), a.runs)
    ref = reference_ms(a.sets)
    report["set"] = {
        "process_many_ms_per_set": many,
        "reference_ms_per_set": ref["median_ms_per_set"],
        "speedup": ref["median_ms_per_set"] / many,
        "in_contact": sum(r.in_contact for r in sensor.process_many(jpegs)),
    }
    print(json.dumps(report["set"]), file=sys.stderr)
    report["gil"] = gil_share(sensor, jpegs[0], a.gil_seconds)
    print(json.dumps(report["gil"]), file=sys.stderr)
    mini = SHARED / "data" / "gelsight-mini-presses"
    with tempfile.TemporaryDirectory() as tmp:
        gelgrip.label(str(mini), str(Path(tmp) / "mini"), 3.68, 0.0317)
        model = gelgrip.train(str(Path(tmp) / "mini"), "lut")
    background = np.asarray(gelgrip.read_image(str(mini / "background.png")))
    frame = np.asarray(gelgrip.read_image(str(mini / "press_006.png")))
    real = gelgrip.Sensor(model, background, noise_frames=[frame])
    ours = median_ms(lambda: real.process(frame), a.runs)
    theirs = numpy_scipy_ms(frame, background, a.runs)
    report["real_press"] = {"process_ms": ours, "numpy_scipy_ms": theirs, "speedup": theirs / ours}
    print(json.dumps(report["real_press"]), file=sys.stderr)
    report["memory"] = memory(sensor, jpegs[0], a.calls)
    print(json.dumps(report))


if __name__ == "__main__":
    main()
