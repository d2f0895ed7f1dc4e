"""Run an ensemble: validate, skip finished members, hand out the rest, write the products.

``python -m fem_runout ensemble CASE.yaml ENSEMBLE.yaml`` and :func:`run_ensemble` both come
here; each member runs through :func:`fem_runout.api.run` on its group's sub-communicator.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fem_runout.ensemble.members import Member, finished, member_case, run_member
from fem_runout.ensemble.pool import MemberPool
from fem_runout.ensemble.sampling import member_parameters
from fem_runout.ensemble.spec import EnsembleSpec, load_ensemble
from fem_runout.errors import CaseError

__all__ = ["EnsembleResult", "prepare", "run_ensemble"]


@dataclass
class EnsembleResult:
    """What an ensemble run returns (the same on every rank).

    Attributes:
        out: The ensemble's folder.
        summary: ``ensemble.json``: members, failures, sensitivity, products.
        ran: Members this call ran (the others were finished before).
    """

    out: Path
    summary: dict[str, Any]
    ran: int


@dataclass(frozen=True)
class _Plan:
    spec: EnsembleSpec
    members: list[Member]
    out: Path
    cases: dict[int, Any]


class _Server:
    """Runner callback: world rank 0 answers the other groups between its own steps."""

    def __init__(self, pool: MemberPool) -> None:
        self.pool = pool

    def start(self, solver, info) -> None:
        self.pool.serve()

    def step(self, solver, info) -> None:
        self.pool.serve()

    def output(self, solver, info) -> None:
        pass

    def finish(self, solver, info) -> None:
        self.pool.serve()


def prepare(case_path: str | Path, spec_path: str | Path, overrides: Sequence[Any] = (),
            out: str | Path | None = None) -> _Plan:
    """Validate the ensemble and every member's case (raise CaseError); write nothing."""
    from fem_runout.config import load_case
    from fem_runout.config.loader import dump_resolved

    spec = load_ensemble(spec_path, case_path)
    base = load_case(case_path, list(overrides))
    default = base.output_dir.with_name(f"{base.output_dir.name}_ensemble")
    folder = Path(out or spec.output.dir or default)
    base_text = dump_resolved(base)
    members = [Member.make(i, v, base_text) for i, v in enumerate(member_parameters(spec))]
    cases = {}
    for m in members:
        try:
            cases[m.index] = member_case(case_path, list(overrides), m, folder)
        except CaseError as exc:
            values = ", ".join(f"{k}={v:.6g}" for k, v in m.values.items())
            raise CaseError(f"{spec_path}: member {m.index} ({values}): {exc}") from None
    return _Plan(spec, members, folder.resolve(), cases)


def _progress(total: int, done: int, quiet: bool):
    if quiet:
        return None
    import sys

    from tqdm import tqdm

    return tqdm(total=total, initial=done, desc="ensemble", unit="member", file=sys.stderr)


def run_ensemble(case_path: str | Path, spec_path: str | Path, *, overrides: Sequence[Any] = (),
                 out: str | Path | None = None, comm=None, quiet: bool = True,
                 plan: _Plan | None = None) -> EnsembleResult:
    """Run the members not finished yet and write the products (collective on ``comm``).

    Args:
        case_path: The base case file.
        spec_path: The ensemble file (:mod:`fem_runout.ensemble.spec`).
        overrides: Overrides of the base case (as for :func:`fem_runout.config.load_case`).
        out: The ensemble's folder (default: the file's ``output.dir``).
        comm: Communicator of the whole ensemble (default COMM_WORLD).
        quiet: No progress bar.
        plan: The result of :func:`prepare` for these arguments, if already made.
    """
    from mpi4py import MPI

    from fem_runout.ensemble.products import write_products

    comm = comm or MPI.COMM_WORLD
    plan = plan or prepare(case_path, spec_path, overrides, out)
    records = {m.index: finished(m, plan.out) for m in plan.members} if comm.rank == 0 else {}
    todo = comm.bcast([i for i, r in records.items() if r is None], root=0)
    if comm.rank == 0:
        (plan.out / "members").mkdir(parents=True, exist_ok=True)
        (plan.out / "ensemble.yaml").write_text(Path(spec_path).read_text())
    bar = _progress(len(plan.members), len(plan.members) - len(todo), quiet or comm.rank != 0)
    pool = MemberPool(comm, todo, plan.spec.ranks_per_member,
                      on_done=(lambda k, n: bar.update(1)) if bar is not None else None)
    last = -1
    while (k := pool.next(last)) is not None:
        run_member(plan.cases[k], plan.members[k], plan.out, pool.group, [_Server(pool)])
        last = k
    pool.close()
    summary = None
    if comm.rank == 0:
        if bar is not None:
            bar.close()
        records = [finished(m, plan.out) for m in plan.members]
        summary = write_products(plan.spec, records, plan.out)
    return EnsembleResult(plan.out, comm.bcast(summary, root=0), len(todo))
