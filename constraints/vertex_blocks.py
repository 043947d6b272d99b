"""The rows of an impact-aware constraint for every vertex of the friction cone's section that the
impulse may take (docs/frictional-impacts.md, "Robust rows on held contacts"): the frictionless
impulse's rows, then the same rows for each edge impulse iota_i = G_i J v' of the impact's
friction rows (``ExpectedImpact.edge_impulse_maps``; the kernels read ``edge_row_impulse_maps``, the writable buffer)."""

from __future__ import annotations

import numpy as np

from .constraint import ControlCycle


class VertexBlocks:
    """Mixin before a frictionless constraint class whose rows read one impulse map G: its rows
    (the first block, unchanged), then one block per edge (``vertex_rows_into`` with G_i);
    unbounded while no impact is coming. The class calls :meth:`stack_vertices` once its rows
    are set."""

    def stack_vertices(self) -> None:
        """(1 + edges) blocks of the frictionless rows."""
        self._block = self.rows
        self.rows = self._block * (1 + self.impact.friction.count)

    def vertex_rows_into(self, terms, cycle: ControlCycle, impulse_map: np.ndarray, C, upper) -> None:
        raise NotImplementedError

    def compute_into(self, terms, cycle: ControlCycle, C, lower, upper) -> None:
        block = self._block
        super().compute_into(terms, cycle, C[:block], lower[:block], upper[:block])
        lower[block:] = -np.inf
        if not self.impact.is_active(terms):
            C[block:] = 0.0
            upper[block:] = np.inf
            return
        for e, impulse_map in enumerate(self.impact.edge_row_impulse_maps(terms)):
            rows = slice((e + 1) * block, (e + 2) * block)
            self.vertex_rows_into(terms, cycle, impulse_map, C[rows], upper[rows])
