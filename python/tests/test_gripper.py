"""The gripper on the runtime the CLI runs: set reports, a grasp of the simulated tennis
ball on the virtual clock (`grasped: true`, as `run --task gentle-grasp`), the bounded
set queue, and the errors of bad scenes and closed grippers."""

from __future__ import annotations

import shutil
import time
from pathlib import Path

import pytest

import gelgrip


def test_a_grasp_of_the_tennis_ball() -> None:
    with gelgrip.Gripper(clock="virtual", scene="tennis-ball") as g:
        s = g.next_set(timeout=30.0)
        assert s.t_s >= 0 and len(s.sensors) == 7 and len(s.fingers) == 3
        assert len(s.servos) == 3 and s.gate["sets"] >= 1
        result = g.grasp(target_force_n=1.5)
        assert result["grasped"] is True, result
        assert result["reason"] and len(result["status"]) == 3
        later = g.next_set(timeout=30.0)
        assert later.t_s > s.t_s
        assert any(f["force_n"] > 0 for f in later.fingers)
        g.release()
        handle = g.start_grasp(target_force_n=1.5)
        again = handle.wait(timeout=60.0)
        assert again["grasped"] is True and handle.done()
        assert handle.wait() == again
        g.stop()
    report = g.close()
    assert report is not None and report["end_reason"] == "signal"
    assert g.closed


def test_an_auto_grasp_finds_its_own_force() -> None:
    # The default config's plain gels: the grasp closes to the preload and settles there
    # (without markers the reflex tightens only on the contact's motion: docs/control.md).
    with gelgrip.Gripper(clock="virtual", scene="tennis-ball") as g:
        g.next_set(timeout=30.0)
        result = g.grasp(target_force_n="auto")
        assert result["grasped"] is True, result
        settled = result["settled_force_n"]
        assert settled is not None and 0.0 < settled < 1.5, result


def test_a_slow_reader_is_told_what_it_missed() -> None:
    with gelgrip.Gripper(clock="virtual", scene="tennis-ball", queue=2) as g:
        g.next_set(timeout=30.0)
        time.sleep(1.0)
        s = g.next_set(timeout=30.0)
        assert s.dropped > 0
        seen = 0
        for s in g.sets():
            seen += 1
            if seen == 3:
                break


def test_bad_requests_and_a_closed_gripper() -> None:
    with pytest.raises(gelgrip.ConfigError, match="no-such-scene"):
        gelgrip.Gripper(clock="virtual", scene="no-such-scene")
    with pytest.raises(ValueError, match="clock"):
        gelgrip.Gripper(clock="wall")
    with pytest.raises(FileNotFoundError):
        gelgrip.Gripper(config="/nonexistent/gripper.toml")
    g = gelgrip.Gripper(clock="virtual", scene="tennis-ball")
    with pytest.raises(ValueError, match="target_force_n"):
        g.grasp(target_force_n=-1.0)
    with pytest.raises(ValueError, match="target_force_n"):
        g.grasp(target_force_n="Auto")  # type: ignore[arg-type]
    g.close()
    for call in (g.release, g.stop, g.estop, lambda: g.grasp(), lambda: g.start_grasp()):
        with pytest.raises(gelgrip.GripperError, match="closed"):
            call()
    with pytest.raises(gelgrip.GripperError):
        g.next_set(timeout=1.0)


def test_ctrl_c_during_a_grasp_raises_and_stops_it() -> None:
    import _thread
    import signal
    import threading

    # Ctrl-C as Python delivers it: a process started in the background by a
    # non-interactive shell (as a CI runner may start the tests) ignores SIGINT, and then
    # `interrupt_main` does nothing; the test sets Python's own handler for its duration.
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with gelgrip.Gripper(clock="virtual", scene="tennis-ball") as g:
            g.next_set(timeout=30.0)
            timer = threading.Timer(0.05, _thread.interrupt_main)
            timer.start()
            with pytest.raises(KeyboardInterrupt):
                g.grasp(target_force_n=1.5)
            timer.join()
            # The fingers were stopped, the run goes on and takes the next grasp.
            assert g.next_set(timeout=30.0).t_s > 0
            assert g.grasp(target_force_n=1.5)["grasped"] is True
    finally:
        signal.signal(signal.SIGINT, previous)


def test_a_config_that_enables_ros_2_is_refused(tmp_path: Path) -> None:
    # The package builds gelgrip without ROS 2 and the dashboard (docs/python.md): a config
    # that publishes to ROS 2 is refused, saying so, rather than run without it.
    configs = Path(__file__).resolve().parents[2] / "configs"
    shutil.copytree(configs, tmp_path / "configs")
    config = tmp_path / "configs" / "gelgripper-sim.toml"
    config.write_text(config.read_text() + "\n[ros]\nenabled = true\n")
    with pytest.raises(gelgrip.ConfigError, match="built without ROS 2"):
        gelgrip.Gripper(config=str(config), clock="virtual")
