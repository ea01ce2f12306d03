"""The memory one job may use, and the guard that holds every documented size to it: one rule for the bake, the
render and the benches.

The tools are sized for a machine with 24 GiB of memory: a job (one bake step, or one render's references and
geometry) may reach BUDGET at its peak, the rest left to the system, and never more than the memory available
when it starts (on a smaller or busier machine). Each piece of work whose documented sizes can reach the budget
estimates its peak from its settings alone, one function per kind, from peaks measured with ru_maxrss or
tracemalloc and rounded up: `kernels.octahedral.bake_bytes` (atlases), `assets.teapot.bake_bytes` (segments),
`kernels.vdm.bake_bytes` (tables), `techniques.billboards.bake_bytes` (maps and their pyramids, per billboard: how
many a projection makes is known only as they are made, so their bake is held to the count that fits), and
`vdmrender.render.check_memory` (the reference per pixel, the geometry per face and per quadric). `check`
refuses an estimate over the budget, with it in the message, before anything is allocated. A setting's
documented maximum is what the guard allows, or the refusal says why not.
"""
from __future__ import annotations

import os

from ..errors import InputError

BUDGET = 20 << 30   # bytes: a 24 GiB machine less 4 GiB for the system, the interpreter and what else runs


def available() -> int:
    """The memory the system reports available now (bytes)."""
    return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")


def allowed(free: int | None = None) -> int:
    """What one job may reach: BUDGET, or the available memory (`free`, measured now if None) where that is less."""
    return min(BUDGET, available() if free is None else free)


def fits(need: int, free: int | None = None) -> bool:
    return need <= allowed(free)


def check(need: int, what: str, fix: str, free: int | None = None) -> None:
    """Refuse `what` when its estimated peak `need` (bytes) is over allowed(`free`); `fix` says what to lower."""
    limit = allowed(free)
    if need > limit:
        which = ("the budget (vdmbake.bundle.budget.BUDGET, for a 24 GiB machine)" if limit == BUDGET
                 else f"the memory available now (the budget is {BUDGET / 2**30:.3g} GiB)")
        raise InputError(f"{what} needs about {need / 2**30:.1f} GiB of memory, more than the {limit / 2**30:.3g} "
                         f"GiB of {which}; {fix}.")
