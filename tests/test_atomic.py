"""Atomic writes: the old file or the new one, never a partial one, and no temporary file left."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import pytest

from impactqp.controller.measured.atomic import write_atomic, write_text_atomic


def test_an_interrupted_write_leaves_the_old_file_and_no_temporary_file(tmp_path):
    target = tmp_path / "dataset.json"
    target.write_text("old")

    def interrupted(tmp):
        tmp.write_text("half")
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        write_atomic(target, interrupted)
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["dataset.json"]


def test_a_written_file_follows_the_umask(tmp_path):
    previous = os.umask(0o002)
    try:
        write_text_atomic(tmp_path / "a.txt", "x")
    finally:
        os.umask(previous)
    assert (tmp_path / "a.txt").stat().st_mode & 0o777 == 0o664


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP])
def test_a_signal_during_a_campaign_leaves_a_consistent_dataset(tmp_path, signum):
    out = tmp_path / "campaign"
    proc = subprocess.Popen(
        [sys.executable, "-m", "impactqp", "campaign", "--postures", "elbow_up", "--speeds",
         "0.08,0.1,0.12,0.15,0.18", "--tangential", "none", "--out", str(out), "--json"],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
    )
    while not (out / "dataset.json").exists() and proc.poll() is None:  # however slow the machine
        time.sleep(0.05)
    proc.send_signal(signum)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode in (0, 130), err
    assert not [p.name for p in out.iterdir() if p.name.startswith(".")]
    manifest = json.loads((out / "dataset.json").read_text())
    for trial in manifest["trials"]:
        assert (out / trial["file"]).stat().st_size > 0 and (out / trial["force_file"]).stat().st_size > 0


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM, signal.SIGHUP])
def test_a_signal_right_after_the_temporary_file_is_created_leaves_no_temporary_file(tmp_path, monkeypatch, signum):
    """A real signal to this process the moment the temporary file exists (right after the real
    os.open that creates it returns): the window of issue 13, where a 0-byte
    ``.dataset.json.*.json`` survived a Ctrl-C."""
    real_open = os.open

    def open_then_signal(file, flags, *args, **kwargs):
        fd = real_open(file, flags, *args, **kwargs)
        if str(file).startswith(str(tmp_path)) and flags & os.O_CREAT:
            os.kill(os.getpid(), signum)
        return fd

    def interrupt(*_):
        raise KeyboardInterrupt

    previous = {sig: signal.signal(sig, interrupt) for sig in (signal.SIGTERM, signal.SIGHUP)}
    monkeypatch.setattr(os, "open", open_then_signal)
    try:
        with pytest.raises(KeyboardInterrupt):
            write_text_atomic(tmp_path / "dataset.json", "{}")
    finally:
        monkeypatch.undo()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    assert list(tmp_path.iterdir()) == []


def test_a_write_the_system_refuses_names_the_target_and_leaves_the_old_file(tmp_path):
    """A real refusal by the kernel (a file-size limit: EFBIG, as ENOSPC on a full disk, carries no
    file name) comes back naming the target; the old file stays and no temporary file is left."""
    target = tmp_path / "table1.json"
    target.write_text("old")
    code = (
        "import resource, signal, sys\n"
        "from impactqp.controller.measured.atomic import write_text_atomic\n"
        "signal.signal(signal.SIGXFSZ, signal.SIG_IGN)\n"
        "resource.setrlimit(resource.RLIMIT_FSIZE, (1000, 1000))\n"
        "try:\n"
        f"    write_text_atomic(sys.argv[1], 'x' * 100_000)\n"
        "except OSError as error:\n"
        "    print(error.filename, error.strerror, sep='|')\n"
    )
    out = subprocess.run([sys.executable, "-c", code, str(target)], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    filename, reason = out.stdout.strip().split("|")
    assert filename == str(target) and reason
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["table1.json"]
