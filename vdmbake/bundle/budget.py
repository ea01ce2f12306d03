"""The memory a bake may use, and the guard that holds every documented size to it.

vdmbake is sized for a machine with 24 GiB of memory: BUDGET is the peak one bake may reach, the rest left to
the system. Each bake step whose documented sizes can reach it estimates its peak from its settings alone, one
function per kind of work, from peaks measured with ru_maxrss and rounded up: `kernels.octahedral.bake_bytes`
(atlases), `assets.teapot.bake_bytes` (segments), `kernels.vdm.bake_bytes` (tables) and
`techniques.billboards.bake_bytes` (maps and their pyramids, per billboard: how many a projection makes is known
only as they are made, so their bake is held to the count that fits). `check` refuses an estimate over BUDGET,
with it in the message, before anything is allocated. A setting's documented maximum is what the guard allows,
or the refusal says why not.
"""
from __future__ import annotations

from ..errors import InputError

BUDGET = 20 << 30   # bytes: a 24 GiB machine less 4 GiB for the system, the interpreter and what else runs


def check(need: int, what: str, fix: str, budget: int | None = None) -> None:
    """Refuse `what` when its estimated peak `need` (bytes) is over `budget` (BUDGET); `fix` says what to lower."""
    budget = BUDGET if budget is None else budget
    if need > budget:
        raise InputError(f"{what} needs about {need / 2**30:.1f} GiB of memory to bake, more than the "
                         f"{budget / 2**30:.3g} GiB budget (vdmbake.bundle.budget.BUDGET, for a 24 GiB machine); "
                         f"{fix}.")
