"""Test processes compile each numba kernel signature once between them (tests/compile_once.py)."""

import fcntl
import json
import os
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
from numba import typeof

import compile_once

TESTS = Path(__file__).parent
KERNEL = textwrap.dedent(
    """
    from numba import njit

    @njit(cache=True)
    def total(x):
        return x.sum()

    @njit(cache=True)
    def untypable(x):
        return x + "a"
    """
)
CHILD = textwrap.dedent(
    """
    import json, sys
    sys.path[:0] = sys.argv[1:3]
    import compile_once
    compile_once.install()
    import numpy as np
    from shared_kernel import total
    total(np.ones(3))
    print(json.dumps([sum(total.stats.cache_hits.values()), sum(total.stats.cache_misses.values())]))
    """
)


def _kernel_module(directory: Path):
    """The module ``shared_kernel`` written in ``directory`` (its numba cache beside it), imported
    here with this process's ``compile_once`` installed (conftest)."""
    (directory / "shared_kernel.py").write_text(KERNEL)
    sys.path.insert(0, str(directory))
    try:
        import shared_kernel
    finally:
        sys.path.remove(str(directory))
    sys.modules.pop("shared_kernel")
    return shared_kernel


def _waiters(path: str) -> int:
    """How many processes wait for the flock of ``path`` (Linux's /proc/locks: the "->" lines)."""
    inode = os.stat(path).st_ino
    lines = Path("/proc/locks").read_text().splitlines()
    return sum("->" in line and line.split()[-3].endswith(f":{inode}") for line in lines)


@pytest.mark.skipif(not Path("/proc/locks").exists(), reason="needs Linux's /proc/locks")
def test_two_processes_missing_the_cache_compile_the_signature_once(tmp_path):
    kernel = _kernel_module(tmp_path).total
    lock = kernel._cache.lock_path((typeof(np.ones(3)),))
    os.makedirs(os.path.dirname(lock), exist_ok=True)
    held = os.open(lock, os.O_RDWR | os.O_CREAT, 0o600)
    fcntl.flock(held, fcntl.LOCK_EX)  # both children miss the empty cache, then wait here
    try:
        children = [
            subprocess.Popen([sys.executable, "-c", CHILD, str(TESTS), str(tmp_path)], stdout=subprocess.PIPE, text=True)
            for _ in range(2)
        ]
        while _waiters(lock) < 2 and all(child.poll() is None for child in children):
            time.sleep(0.05)  # polling, not a deadline: no outcome depends on how long it takes
    finally:
        os.close(held)
    counts = [json.loads(child.communicate()[0]) for child in children]
    assert all(child.returncode == 0 for child in children)
    assert sorted(counts) == [[0, 1], [1, 0]]  # one compiled and saved it, the other loaded it


def test_a_failed_compile_releases_its_lock_and_fails_again_in_the_same_process(tmp_path):
    kernel = _kernel_module(tmp_path).untypable
    for _ in range(2):  # the second call does not wait for a lock this process still holds
        with pytest.raises(Exception, match="(?i)typing"):
            kernel(1.0)
    lock = os.open(kernel._cache.lock_path((typeof(1.0),)), os.O_RDWR)
    try:
        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)  # raises BlockingIOError while held
    finally:
        os.close(lock)


def test_the_kernels_of_the_package_use_the_serialised_cache():
    from impactqp.controller.model.crb_prediction import crb_batch

    assert isinstance(crb_batch._cache, compile_once.SerialisedFunctionCache)
