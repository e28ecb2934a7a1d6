"""``cosim envelope SPEC.yaml``: the mismatch at which a requirement starts to fail, found by
root-finding on its robustness over a seed ensemble (:mod:`cosim.sweeps.envelope_search`),
on the sweep's process pool or on Ray.

The search runs in rounds: each open bracket (a ray and a seed) asks for its next point,
the round's runs go to the backend together, and their robustness moves the brackets; with
two parameters, rays are added where the boundary points of neighbouring rays lie far
apart. Every run is a row of ``results.jsonl`` keyed by its values and seed, so the same
spec asks for the same runs in the same order and ``--resume`` takes the finished ones from
the file (the search is deterministic given the rows).

Outputs in ``--out DIR``: ``envelope.json`` (per ray and seed the critical value, per ray
the ensemble's boundary, the runs taken), ``summary.md`` (the answer in words), and
``envelope.png`` (the boundary with the nominal point, every run and the margin).
"""

from __future__ import annotations

import json
import math
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cosim.core.exceptions import CosimError
from cosim.sweeps.envelope_search import (
    FIRST_RAYS,
    Bracket,
    Ray,
    axis_ray,
    ensemble_boundary,
    plane_ray,
    rays_to_add,
)
from cosim.sweeps.envelope_spec import EnvelopeSpec, load_envelope_spec
from cosim.sweeps.results import append_row, read_row_log, refuse_non_empty
from cosim.sweeps.spec import RunTask, unit_of

ROWS_FILE = "results.jsonl"
SPEC_FILE = "envelope-spec.json"

Key = tuple[tuple[float, ...], int]
"""A run: its parameter values and its seed."""


def run_passes(row: dict[str, Any]) -> tuple[bool, float]:
    """Whether a run passed (no error, outcome ``ok``, robustness >= 0) and its robustness
    (NaN when it has none to give: an error, or a run that stopped early)."""
    metrics = row.get("metrics", {})
    value = metrics.get("stl_robustness")
    if row.get("error") or metrics.get("outcome") != "ok" or not isinstance(value, float) \
            or not math.isfinite(value):
        return False, math.nan
    return value >= 0.0, value


@dataclass
class RaySearch:
    """One ray and a bracket per seed."""

    ray: Ray
    brackets: dict[int, Bracket]

    def critical_shares(self) -> list[float]:
        return [b.critical_s for b in self.brackets.values()]


@dataclass
class EnvelopeResult:
    """What the search found."""

    spec: EnvelopeSpec
    rays: list[RaySearch]
    runs: int
    """Distinct runs the search took (from this invocation and earlier ones)."""
    ran: int
    """Runs this invocation ran."""
    wall_time_s: float
    files: list[Path] = field(default_factory=list)

    def boundary_s(self, search: RaySearch) -> float:
        return ensemble_boundary(search.critical_shares(), self.spec.failure_rate)


def _initial_rays(spec: EnvelopeSpec) -> list[Ray]:
    if len(spec.parameters) == 1:
        return [axis_ray(1, 0)]
    return [plane_ray(90.0 * i / (FIRST_RAYS - 1)) for i in range(FIRST_RAYS)]


def search(spec: EnvelopeSpec, evaluate: Callable[[list[Key]], dict[Key, dict[str, Any]]],
           ) -> tuple[list[RaySearch], dict[Key, dict[str, Any]]]:
    """Run the search with ``evaluate`` (a batch of runs -> their rows); returns the rays
    and every row by key."""
    rows: dict[Key, dict[str, Any]] = {}
    searches = [RaySearch(ray, {seed: Bracket(spec.resolution_s(ray.direction))
                                for seed in spec.seeds}) for ray in _initial_rays(spec)]
    while True:
        wanted: dict[Key, list[tuple[RaySearch, int, float]]] = {}
        for item in searches:
            for seed, bracket in item.brackets.items():
                s = bracket.next_s()
                if s is None:
                    continue
                values = tuple(p.value(u) for p, u in zip(
                    spec.parameters, item.ray.unit_point(s), strict=True))
                wanted.setdefault((values, seed), []).append((item, seed, s))
        if not wanted:
            if len(spec.parameters) < 2:
                break
            boundary = [ensemble_boundary(r.critical_shares(), spec.failure_rate)
                        for r in searches]
            added = rays_to_add([r.ray for r in searches], boundary, ray_spacing(spec),
                                spec.max_rays)
            if not added:
                break
            searches += [RaySearch(ray, {seed: Bracket(spec.resolution_s(ray.direction))
                                         for seed in spec.seeds}) for ray in added]
            continue
        missing = [key for key in wanted if key not in rows]
        rows.update(evaluate(missing))
        for key, askers in wanted.items():
            passed, score = run_passes(rows[key])
            for item, seed, s in askers:
                item.brackets[seed].record(s, score, passed)
    return searches, rows


def ray_spacing(spec: EnvelopeSpec) -> float:
    """How far apart (in box units) the boundary points of neighbouring rays may lie
    before a ray is added between them: four resolution steps of the coarser axis."""
    steps = [spec.resolution * (abs(p.nominal) or abs(p.limit - p.nominal))
             / abs(p.limit - p.nominal) for p in spec.parameters]
    return max(0.02, 4.0 * max(steps))


class EnvelopeDir:
    """The output folder: the spec as resolved, the row log, the outputs."""

    def __init__(self, root: Path, spec: EnvelopeSpec) -> None:
        self.root = root
        self.spec = spec

    def prepare(self, resume: bool, force: bool) -> dict[Key, dict[str, Any]]:
        """Make the folder (refusing one with files unless ``force`` or ``resume``) and
        return the rows of an earlier invocation of the same spec (``resume``)."""
        # The runs a search took stay valid whatever the ray budget: more rays resume it.
        digest = json.dumps({k: v for k, v in self.spec.to_dict().items() if k != "max_rays"},
                            sort_keys=True, default=str)
        spec_file = self.root / SPEC_FILE
        if resume:
            if not spec_file.is_file():
                raise CosimError(f"--resume: {str(self.root)!r} holds no envelope search: "
                                 "expected the --out of an earlier cosim envelope")
            if spec_file.read_text() != digest:
                raise CosimError(f"--resume: {str(self.root)!r} holds a search of another "
                                 "spec: expected the same spec (or --force to start afresh)")
        else:
            if not force:
                refuse_non_empty(self.root, "start afresh", "finish the search it holds")
            if force and self.root.is_dir():
                for path in self.root.iterdir():
                    if path.is_file():
                        path.unlink()
        self.root.mkdir(parents=True, exist_ok=True)
        spec_file.write_text(digest)
        rows = read_row_log(self.root / ROWS_FILE)
        return {(tuple(r["values"]), r["seed"]): r for r in rows.values()}


def run_envelope(spec_path: str | Path, out_dir: Path, workers: int | None,
                 backend: str, resume: bool = False, force: bool = False) -> EnvelopeResult:
    """Search the envelope of ``spec_path`` into ``out_dir`` (module docstring)."""
    from cosim.sweeps.driver import sigterm_as_interrupt
    from cosim.sweeps.execute import make_backend

    start = time.perf_counter()
    spec = load_envelope_spec(spec_path)
    runner = make_backend(backend, workers, spec.ray_address)
    directory = EnvelopeDir(Path(out_dir), spec)
    earlier = directory.prepare(resume, force)
    ran = 0
    next_id = max((r["run_id"] for r in earlier.values()), default=-1) + 1

    with (directory.root / ROWS_FILE).open("a", encoding="utf-8") as handle:

        def evaluate(keys: list[Key]) -> dict[Key, dict[str, Any]]:
            nonlocal ran, next_id
            found = {key: earlier[key] for key in keys if key in earlier}
            tasks, by_id = [], {}
            for key in keys:
                if key in found:
                    continue
                values, seed = key
                params = tuple((p.path, v) for p, v in zip(spec.parameters, values,
                                                           strict=True))
                task = RunTask(next_id, 0, seed, params, spec.scenario,
                               spec.overrides(values), spec.tracker, spec.estimator,
                               spec.duration_s, None)
                by_id[next_id] = key
                next_id += 1
                tasks.append(task)

            def land(row: dict[str, Any]) -> None:
                nonlocal ran
                if row.get("interrupted"):
                    return
                key = by_id[row["run_id"]]
                row["values"] = list(key[0])
                append_row(handle, row)
                found[key] = row
                ran += 1

            if tasks:  # a line a round: a search of many rounds says how far it is
                print(f"envelope: {len(tasks)} more run(s) ({ran} done so far)",
                      file=sys.stderr, flush=True)
                runner.run(tasks, land)
            if len(found) < len(keys):
                raise KeyboardInterrupt  # a run was interrupted: --resume goes on
            return found

        with sigterm_as_interrupt():  # SIGTERM as Ctrl-C: the rows so far are kept
            searches, rows = search(spec, evaluate)
    result = EnvelopeResult(spec, searches, len(rows), ran, time.perf_counter() - start)
    from cosim.sweeps.envelope_report import write_outputs

    result.files = write_outputs(result, rows, directory.root)
    return result


def parameter_boundary(result: EnvelopeResult, search_item: RaySearch) -> dict[str, Any]:
    """One ray's answer in parameter units: the ensemble's boundary and each seed's."""
    spec = result.spec

    def at(s: float) -> list[float | None]:
        if math.isinf(s):
            return [None for _ in spec.parameters]
        return [p.value(u) for p, u in zip(spec.parameters, search_item.ray.unit_point(s),
                                           strict=True)]

    shares = search_item.critical_shares()
    return {
        "angle_deg": search_item.ray.angle_deg,
        "direction": list(search_item.ray.direction),
        "boundary_s": _finite(result.boundary_s(search_item)),
        "boundary": at(result.boundary_s(search_item)),
        "seeds": {str(seed): {"critical_s": _finite(b.critical_s), "critical": at(b.critical_s),
                              "runs": len(b.evaluated)}
                  for seed, b in search_item.brackets.items()},
        "critical_s_range": [_finite(min(shares)), _finite(max(shares))],
    }


def _finite(value: float) -> float | None:
    return value if math.isfinite(value) else None


def unit_text(path: str) -> str:
    unit = unit_of(path)
    return "" if unit in ("-", "1") else f" {unit}"
