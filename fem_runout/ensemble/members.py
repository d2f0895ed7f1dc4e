"""One ensemble member: its case, its key, its folder, and running it with the one run path.

A member's folder is ``<out>/members/<key>`` where the key hashes the base case (resolved) and
the member's parameter values: rerunning the ensemble finds the members already finished (their
``member.json``, written last and atomically) and skips them, and a changed case or parameter
never reuses an old result.
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

__all__ = ["Member", "MEMBER_FILE", "finished", "member_case", "run_member"]

MEMBER_FILE = "member.json"


@dataclass(frozen=True)
class Member:
    """A member of the ensemble.

    Attributes:
        index: Position in the sampling plan.
        values: Varied case key -> value.
        key: Hash of the base case and the values (the folder name).
    """

    index: int
    values: dict[str, float]
    key: str

    @classmethod
    def make(cls, index: int, values: dict[str, float], base: str) -> Member:
        """Key a member by the base case's text and its values (exact float reprs)."""
        text = base + json.dumps({k: repr(float(v)) for k, v in sorted(values.items())})
        return cls(index, dict(values), hashlib.sha256(text.encode()).hexdigest()[:16])

    def folder(self, out: Path) -> Path:
        """Return the member's output folder."""
        return out / "members" / self.key


def member_case(case_path: str | Path, overrides: list[Any], member: Member, out: Path):
    """Return the validated case of ``member`` (its values, its folder, no pictures)."""
    from fem_runout.config import load_case

    extra = [(k, v) for k, v in member.values.items()]
    extra += [("output.dir", str(member.folder(out))), ("output.pictures", False)]
    return load_case(case_path, [*overrides, *extra])


def finished(member: Member, out: Path) -> dict[str, Any] | None:
    """Return the record of a finished member (its ``member.json``), or None."""
    path = member.folder(out) / MEMBER_FILE
    try:
        record = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return record if record.get("key") == member.key else None


def run_member(case, member: Member, out: Path, comm, callbacks=()) -> dict[str, Any]:
    """Run a member on ``comm`` (collective); write and return its record on every rank.

    A member whose state goes bad (NaN, negative depth) is recorded with its error and left
    out of the products; the ensemble goes on.
    """
    from fem_runout.api import run

    result = run(case, overwrite=True, quiet=True, comm=comm, callbacks=callbacks,
                 raise_errors=False)
    record = {"index": member.index, "key": member.key, "values": member.values,
              "error": result.error, "summary": result.summary}
    if comm.rank == 0:
        path = member.folder(out) / MEMBER_FILE
        tmp = path.with_suffix(".tmp")
        tmp.write_text(json.dumps(record, indent=1, default=float) + "\n")
        os.replace(tmp, path)
    return record
