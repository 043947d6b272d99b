"""daqp's C API on a workspace of our own (``DaqpWorkspace``), without daqp's Python wrapper.

daqp solves min 1/2 x^T H x + f^T x s.t. blower <= [x; A x] <= bupper (the first ``ms`` bounds
simple) by a dual active-set method on the least-distance problem of R^-T (R x + v), R^T R = H.
Its Python module (``daqp.Model``) keeps a workspace too, but each ``update`` converts five
arrays to typed memoryviews and each ``solve`` copies its result and builds a dictionary: more
time than the solve of a small QP itself (docs/controller.md, "Eighth round").

The functions are the C library's own, exported by daqp's extension module (``daqp.__file__``);
the setup is called through ``ctypes``, the update and the solve of every cycle from a compiled
kernel (``workspace_solve``: the two symbols are made known to numba's linker, so the kernel is
cached like the others):

- ``setup_daqp_main(qp, work, &setup_time, 0)``: the workspace of a problem with the default
  settings (R, M = A R^-1 and the scaled bounds), >= 0 on success, < 0 for an inconsistent
  problem (lb > ub somewhere), its arrays then freed;
- ``daqp_update_ldp(mask, work, qp)``: the parts of the workspace named by ``mask`` computed
  again from the problem's arrays (read in place: the problem's pointers are our buffers);
- ``daqp_solve(result, work)``: the solve from the workspace's working set (a warm start);
- ``free_daqp_workspace(work)``, ``free_daqp_ldp(work)``: the workspace's arrays freed (each
  does nothing to arrays already freed).

An update of H and A keeps the previous solve's working set by naming the workspace's own
constraint states as the problem's ``sense`` (what ``daqp.Model.update`` does when no sense is
given). The structures' layouts are those of daqp's C headers (``types.h``, ``api.h``) of the
version the project pins (pyproject.toml); the workspace is opaque but for its leading fields,
up to the pointer to those states.
"""

from __future__ import annotations

import ctypes
import weakref

import daqp
import llvmlite.binding
import numpy as np
from numba import njit, types

from .problem import QpProblem

_int, _double, _pointer = ctypes.c_int, ctypes.c_double, ctypes.c_void_p

UPDATE_ALL = 1 | 2 | 4 | 8 | 16  # DAQP_UPDATE_Rinv | _M | _v | _d | _sense: every datum and the working set
WORKSPACE_BYTES = 4096  # more than daqp's DAQPWorkspace (about 330 bytes): the library reads its fields only


class DaqpProblem(ctypes.Structure):
    """daqp's ``DAQPProblem``: sizes, the data's pointers, the constraints' states (``sense``)."""

    _fields_ = [
        ("n", _int), ("m", _int), ("ms", _int), ("H", _pointer), ("f", _pointer), ("A", _pointer),
        ("bupper", _pointer), ("blower", _pointer), ("sense", _pointer), ("break_points", _pointer),
        ("nh", _int), ("problem_type", _int),
    ]


class DaqpResult(ctypes.Structure):
    """daqp's ``DAQPResult``: where the solution and multipliers go, and the solve's outcome."""

    _fields_ = [
        ("x", _pointer), ("lam", _pointer), ("fval", _double), ("soft_slack", _double), ("exitflag", _int),
        ("iter", _int), ("nodes", _int), ("solve_time", _double), ("setup_time", _double),
    ]


class WorkspaceHead(ctypes.Structure):
    """The leading fields of daqp's ``DAQPWorkspace``, up to its constraint states (``sense``)."""

    _fields_ = [
        ("qp", _pointer), ("n", _int), ("m", _int), ("ms", _int), ("M", _pointer), ("dupper", _pointer),
        ("dlower", _pointer), ("Rinv", _pointer), ("v", _pointer), ("sense", _pointer),
    ]


def _library() -> ctypes.CDLL:
    """daqp's extension module as a C library, with the signatures of the functions used here."""
    library = ctypes.CDLL(daqp.__file__)
    signatures = {
        "setup_daqp_main": (_int, [_pointer, _pointer, _pointer, _int]),
        "free_daqp_workspace": (None, [_pointer]),
        "free_daqp_ldp": (None, [_pointer]),
    }
    for name, (result, arguments) in signatures.items():
        function = getattr(library, name)
        function.restype, function.argtypes = result, arguments
    return library


_LIBRARY = _library()
for _name in ("daqp_update_ldp", "daqp_solve"):  # for the compiled kernel below, by name
    llvmlite.binding.add_symbol(_name, ctypes.cast(getattr(_LIBRARY, _name), _pointer).value)
# The pointers as 64-bit integers (the same registers in the C calling convention of x86-64 and arm64).
_update_ldp = types.ExternalFunction("daqp_update_ldp", types.intc(types.intc, types.int64, types.int64))
_solve = types.ExternalFunction("daqp_solve", types.void(types.int64, types.int64))
ADDRESSES = 3  # a workspace's words: the workspace's, its problem's and its result's addresses, then the result
SOLUTION_WORD = ADDRESSES + DaqpResult.x.offset // 8  # the result's pointer to the solution
EXIT_WORD = ADDRESSES + DaqpResult.exitflag.offset // 8  # the 64-bit word whose low half is the exit flag
_LOW_HALF = DaqpResult.exitflag.offset % 8 == 0  # where the flag sits in its word (little-endian machines)


@njit(cache=True)
def workspace_solve(words, x):
    """Kernel: update every datum of the workspace from its problem's arrays, then solve from the
    previous working set, the solution written into x (``words``: ``DaqpWorkspace.words``, whose
    result points back to the workspace's own solution buffer afterwards). daqp's exit flag (the
    update's when it fails, < 0)."""
    flag = _update_ldp(UPDATE_ALL, words[0], words[1])
    if flag < 0:
        return flag
    own = words[SOLUTION_WORD]
    words[SOLUTION_WORD] = x.ctypes.data
    _solve(words[2], words[0])
    words[SOLUTION_WORD] = own
    word = words[EXIT_WORD] if _LOW_HALF else words[EXIT_WORD] >> 32
    low = word & 0xFFFFFFFF
    return low - (1 << 32) if low >= (1 << 31) else low  # the signed 32-bit flag


def _release(memory: np.ndarray, address: int) -> None:
    """Free the arrays of the workspace held in ``memory`` (numpy's, zeros before any setup) at
    ``address`` (``memory`` is an argument so that a finalizer keeps it alive until then)."""
    assert _address(memory) == address
    _LIBRARY.free_daqp_workspace(address)
    _LIBRARY.free_daqp_ldp(address)


def _address(array: np.ndarray) -> int:
    """The address of an array's data (``ndarray.ctypes`` builds an object at each read: slower)."""
    return array.__array_interface__["data"][0]


class DaqpWorkspace:
    """One daqp workspace for QPs of ``variables`` unknowns and ``rows`` general rows, read from
    a ``QpProblem``'s arrays in place (its H, g, C and stacked bounds [lb; l], [ub; u]).

    ``setup(problem)`` makes the workspace of ``problem`` (a cold start); ``solve()`` then
    updates every datum from the same arrays, keeps the previous working set and solves. The
    solution is written into the workspace's ``solution`` buffer and copied out. A compiled
    caller solves with ``workspace_solve(words, x)``: ``words`` holds the addresses of the
    workspace, its problem and its result, then the result itself (``DaqpResult``), in 64-bit
    words.
    """

    def __init__(self, rows: int, variables: int):
        self.rows, self.variables = rows, variables
        self._memory = np.zeros(WORKSPACE_BYTES, dtype=np.uint8)
        self._work = _address(self._memory)
        weakref.finalize(self, _release, self._memory, self._work)
        self.solution = np.zeros(variables)
        self._lam = np.zeros(variables + rows)
        self._sense = np.zeros(variables + rows, dtype=np.intc)  # a cold start's: every constraint inactive
        self._qp = DaqpProblem(variables, variables + rows, variables)
        self.words = np.zeros(ADDRESSES + ctypes.sizeof(DaqpResult) // 8, dtype=np.int64)
        self._result = DaqpResult.from_buffer(self.words, ADDRESSES * 8)
        self._result.x, self._result.lam = _address(self.solution), _address(self._lam)
        self.words[:ADDRESSES] = self._work, ctypes.addressof(self._qp), ctypes.addressof(self._result)
        self._qp_pointer = ctypes.byref(self._qp)
        self._setup_time = _double(0.0)
        self._held: tuple = ()  # the arrays the problem's pointers point into
        self._ready = False  # a problem is set up

    def setup(self, problem: QpProblem) -> int:
        """The workspace of ``problem`` from scratch: daqp's exit flag (< 0: inconsistent bounds).
        ``problem``'s arrays must be C-contiguous float64 of this workspace's sizes."""
        arrays = (problem.H, problem.g, problem.C, problem.upper, problem.lower)
        if problem.C.shape != (self.rows, self.variables) or not all(_in_place(a) for a in arrays):
            raise ValueError(f"daqp reads C-contiguous float64 arrays of {self.rows} rows in {self.variables} unknowns")
        _release(self._memory, self._work)
        self._memory.fill(0)
        self._ready = False
        qp = self._qp
        qp.H, qp.f, qp.A, qp.bupper, qp.blower = (_address(a) for a in arrays)
        self._sense.fill(0)
        qp.sense = _address(self._sense)
        self._held = arrays
        flag = _LIBRARY.setup_daqp_main(self._qp_pointer, self._work, ctypes.byref(self._setup_time), 0)
        if flag >= 0:
            qp.sense = WorkspaceHead.from_address(self._work).sense  # the working set, kept by every update
            self._ready = True
        return flag

    def solve(self) -> tuple[int, np.ndarray]:
        """Update every datum from the set-up problem's arrays, then solve from the previous working
        set: (daqp's exit flag, x) (flag >= 1: solved; -1: infeasible; an update's negative flag
        when the bounds are inconsistent). After a failure the next call must be a ``setup``: the
        next problem starts cold."""
        if not self._ready:
            raise RuntimeError("no problem is set up in this daqp workspace")
        flag = workspace_solve(self.words, self.solution)
        self._ready = flag >= 1
        return flag, self.solution.copy()


def _in_place(array: np.ndarray) -> bool:
    return array.dtype == np.float64 and array.flags.c_contiguous
