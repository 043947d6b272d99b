"""One compile of each numba kernel signature for all the test processes of one checkout.

The kernels are ``@njit(cache=True)``: a compiled signature is saved in numba's on-disk cache
(``__pycache__`` next to the source) and loaded by any later process. On a fresh checkout that
cache is empty, and the two pytest-xdist workers (and the process pools the tests start) would
each compile the same signature when both need it before either has saved it. ``install`` makes
every cached dispatcher created afterwards use ``SerialisedFunctionCache``: on a cache miss the
process takes an exclusive lock on that signature (``fcntl.flock`` on a file of the temporary
directory named after the cache's path, the function and the signature), looks in the cache
again (a process that held the lock has saved it meanwhile: loaded, not compiled) and else
compiles it holding the lock, released once it is saved, or when its compile fails.
"""

from __future__ import annotations

import fcntl
import hashlib
import os
import tempfile

import numba.core.event as numba_event
from numba.core.caching import FunctionCache
from numba.core.dispatcher import Dispatcher
from numba.core.sigutils import normalize_signature

LOCK_DIRECTORY = os.path.join(tempfile.gettempdir(), f"impactqp-numba-compiles-{os.getuid()}")


class SerialisedFunctionCache(FunctionCache):
    """numba's on-disk cache of one function whose misses are compiled by one process at a time."""

    def __init__(self, py_func):
        super().__init__(py_func)
        self._held: dict[str, int] = {}  # signature: the descriptor of its held lock file

    def lock_path(self, sig) -> str:
        """The lock file of ``sig``: one per checkout's cache path, function and argument types."""
        function = f"{self._py_func.__module__}.{self._py_func.__qualname__}"
        key = f"{self.cache_path}|{function}|{_arguments(sig)}".encode()
        return os.path.join(LOCK_DIRECTORY, hashlib.sha256(key).hexdigest()[:32] + ".lock")

    def load_overload(self, sig, target_context):
        loaded = super().load_overload(sig, target_context)
        if loaded is not None:
            return loaded
        if _arguments(sig) in self._held:  # this process is compiling it (a kernel that calls itself)
            return None
        os.makedirs(LOCK_DIRECTORY, exist_ok=True)
        descriptor = os.open(self.lock_path(sig), os.O_RDWR | os.O_CREAT, 0o600)
        fcntl.flock(descriptor, fcntl.LOCK_EX)
        loaded = super().load_overload(sig, target_context)
        if loaded is not None:
            os.close(descriptor)
            return loaded
        self._held[_arguments(sig)] = descriptor
        return None

    def save_overload(self, sig, data):
        try:
            super().save_overload(sig, data)
        finally:
            self.release(sig)

    def release(self, sig) -> None:
        """Let other processes compile ``sig`` (closing the lock file releases its lock)."""
        descriptor = self._held.pop(_arguments(sig), None)
        if descriptor is not None:
            os.close(descriptor)


class _FailedCompileRelease(numba_event.Listener):
    """Releases the lock of a signature whose compile raised (no save follows it)."""

    def on_start(self, event):
        pass

    def on_end(self, event):
        # A compile that raised added no overload (numba's ``Event.is_failed`` is inverted).
        dispatcher, arguments = event.data["dispatcher"], tuple(event.data["args"])
        cache = getattr(dispatcher, "_cache", None)
        if isinstance(cache, SerialisedFunctionCache) and arguments not in dispatcher.overloads:
            cache.release(arguments)


def _arguments(sig) -> str:
    """The argument types of a signature (a tuple of types or a ``Signature``), as text."""
    return str(tuple(normalize_signature(sig)[0]))


def _enable_serialised_caching(dispatcher: Dispatcher) -> None:
    dispatcher._cache = SerialisedFunctionCache(dispatcher.py_func)


def install() -> None:
    """Every cached dispatcher created from now on (``@njit(cache=True)`` of the modules imported
    after this call) compiles its misses one process at a time."""
    Dispatcher.enable_caching = _enable_serialised_caching
    numba_event.register("numba:compile", _FailedCompileRelease())
