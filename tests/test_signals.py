"""Signals against a real ``hysbench run``: SIGINT stops it within 2 s keeping the cells that finished, and
its workers die with it when it is killed (SIGKILL). Linux only (processes found through /proc)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytestmark = pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="processes are listed through /proc")

# one fast cell (classical-pi/varpro, about a second) and one long one (bouc-wen/lsq, tens of seconds)
RUN = ["-m", "hysbench.benchmarks.cli", "run", "--models", "classical-pi,bouc-wen", "--methods", "varpro",
       "--jobs", "2", "--quiet"]


def _children(pid: int) -> list[int]:
    """Every living process whose parent is ``pid``."""
    out = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        fields = stat[stat.rindex(")") + 2:].split()
        if int(fields[1]) == pid and fields[0] != "Z":
            out.append(int(entry.name))
    return out


def _alive(pid: int) -> bool:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat[stat.rindex(")") + 2:].split()[0] != "Z"


def _wait_for(condition, timeout: float, what: str):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        value = condition()
        if value:
            return value
        time.sleep(0.1)
    pytest.fail(f"timed out after {timeout:.0f} s waiting for {what}")


def _start(out: Path) -> subprocess.Popen:
    """The run, its output to files beside ``out``: a pipe nobody reads until the run ends would stop it at
    its first 64 KiB of output (its workers write warnings to the same stderr). stdin from /dev/null:
    under xdist the test process's own stdin is its channel to the controller."""
    out.parent.mkdir(parents=True, exist_ok=True)
    with open(out.parent / "run.stdout", "wb") as so, open(out.parent / "run.stderr", "wb") as se:
        return subprocess.Popen([sys.executable, *RUN, "--out", str(out)], stdin=subprocess.DEVNULL, stdout=so,
                                stderr=se, start_new_session=True)


def _signal_masks(pid: int) -> str:
    lines = Path(f"/proc/{pid}/status").read_text().splitlines()
    return " ".join(l.replace("\t", "") for l in lines if l.startswith(("SigBlk", "SigIgn", "SigCgt")))


def _stderr(out: Path) -> str:
    return (out.parent / "run.stderr").read_bytes().decode(errors="replace")


def _kill_group(proc: subprocess.Popen) -> None:
    """Whatever the test's outcome, nothing it started is left running (the run is its own process group)."""
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    proc.wait()


def _stored_cells(out: Path) -> list[dict]:
    return [json.loads(p.read_text()) for p in (out / "cells").glob("*.json")] if (out / "cells").is_dir() else []


def test_sigint_stops_a_run_within_two_seconds_keeping_finished_cells(tmp_path):
    out = tmp_path / "results"
    proc = _start(out)
    try:
        _wait_for(lambda: _stored_cells(out), 120, "the first finished cell")
        assert proc.poll() is None, "the run finished before the long cell could be interrupted"
        workers = _children(proc.pid)
        t0 = time.monotonic()
        masks = _signal_masks(proc.pid)
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            pytest.fail(f"still running 10 s after SIGINT; run {masks}; test process {_signal_masks(os.getpid())}")
        stopped_after = time.monotonic() - t0
        stderr = _stderr(out)
    finally:
        _kill_group(proc)
    assert stopped_after < 2.0, f"stopped {stopped_after:.1f} s after SIGINT"
    assert proc.returncode == 130
    assert stderr.strip().splitlines()[-1] == "hysbench run: interrupted"
    assert "Traceback" not in stderr
    kept = _stored_cells(out)
    assert [c["model"] for c in kept] == ["classical-pi"] and kept[0]["status"] == "ok"
    _wait_for(lambda: not any(_alive(w) for w in workers), 5, "the workers to exit")


def test_workers_die_with_a_killed_parent(tmp_path):
    proc = _start(tmp_path / "results")
    try:
        workers = _wait_for(lambda: [p for p in _children(proc.pid)
                                     if b"spawn_main" in Path(f"/proc/{p}/cmdline").read_bytes()], 60,
                            "the worker processes")
        assert workers
        family = _children(proc.pid)  # the workers and multiprocessing's resource tracker
        proc.kill()  # SIGKILL: the parent runs no code of its own
        proc.wait()
        _wait_for(lambda: not any(_alive(p) for p in family), 10, f"processes {family} to exit after the parent's death")
    finally:
        _kill_group(proc)
