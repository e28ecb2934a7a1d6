"""What ``cosim envelope`` writes: the answer in words, ``envelope.json`` and the figure."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from cosim.sweeps.envelope import EnvelopeResult, RaySearch, parameter_boundary, unit_text
from cosim.sweeps.envelope_search import Ray
from cosim.sweeps.envelope_spec import SearchParameter
from cosim.sweeps.spec import axis_label


def _seeds_text(seeds: tuple[int, ...]) -> str:
    ordered = sorted(seeds)
    if len(ordered) > 2 and ordered == list(range(ordered[0], ordered[-1] + 1)):
        return f"seeds {ordered[0]}-{ordered[-1]}"
    return "seed " + ", ".join(map(str, ordered)) if len(ordered) == 1 else \
        "seeds " + ", ".join(map(str, ordered))


def _percent(parameter: SearchParameter, value: float) -> str:
    if parameter.nominal == 0.0:
        return f"{value:.4g}{unit_text(parameter.path)}"
    return f"{100.0 * abs(value - parameter.nominal) / abs(parameter.nominal):.1f} %"


def axis_sentence(result: EnvelopeResult, item: RaySearch, index: int) -> str:
    """The answer along one parameter alone, in words."""
    spec = result.spec
    parameter = spec.parameters[index]
    unit = unit_text(parameter.path)
    way = "above" if parameter.limit > parameter.nominal else "below"
    belief = (f" while the controller believes `{parameter.belief}` = "
              f"{_shown(parameter.belief_value)}" if parameter.belief else "")
    level = f"more than {100.0 * spec.failure_rate:g} % of the seeds"
    boundary = result.boundary_s(item)
    shares = sorted(item.critical_shares())
    seeds = _seeds_text(spec.seeds)
    if boundary == 0.0:
        return (f"`{parameter.path}`: `{spec.requirement}` already fails at the nominal "
                f"{parameter.nominal:g}{unit} for {level}: there is no envelope to find.")
    if math.isinf(boundary):
        return (f"`{parameter.path}` may go all the way to the search limit "
                f"{parameter.limit:g}{unit} ({_percent(parameter, parameter.limit)} {way} its "
                f"nominal {parameter.nominal:g}{unit}){belief}: `{spec.requirement}` fails "
                f"for no more than {100.0 * spec.failure_rate:g} % of {seeds} there.")
    value = parameter.value(boundary)
    finite = [s for s in shares if math.isfinite(s)]
    low = _percent(parameter, parameter.value(shares[0]))
    high = ("beyond the limit" if math.isinf(shares[-1]) else
            _percent(parameter, parameter.value(shares[-1])))
    spread = f"{seeds}: {low} to {high}" if finite else seeds
    return (f"`{parameter.path}` may be up to {_percent(parameter, value)} {way} its nominal "
            f"{parameter.nominal:g}{unit} (to {value:.4g}{unit}; {spread}){belief} before "
            f"`{spec.requirement}` fails for {level}.")


def _shown(value: Any) -> str:
    return f"{value:g}" if isinstance(value, float) else str(value)


def summary_markdown(result: EnvelopeResult, axis_items: list[tuple[int, RaySearch]]) -> str:
    spec = result.spec
    lines = [f"# Envelope {spec.name}", ""]
    if spec.description:
        lines += [spec.description, ""]
    lines += [
        f"- scenario `{Path(spec.scenario).name}`, tracker `{spec.tracker_name}`, estimator "
        f"`{spec.estimator_name}`; {_seeds_text(spec.seeds)}",
        f"- requirement `{spec.requirement}`; boundary where more than "
        f"{100.0 * spec.failure_rate:g} % of the seeds fail; resolution "
        f"{100.0 * spec.resolution:g} % of each nominal value",
        f"- {result.runs} runs ({result.ran} in this invocation, "
        f"{result.wall_time_s:.0f} s); {len(result.rays)} ray(s)",
        "", "## The answer", ""]
    lines += [axis_sentence(result, item, index) for index, item in axis_items]
    if len(spec.parameters) == 2:
        lines += ["", "## The boundary of both together", "",
                  "Along each ray from the nominal point (the share of the way to each "
                  "parameter's limit): where the requirement starts to fail.", "",
                  "| angle [deg] | " + " | ".join(f"`{p.path}`" for p in spec.parameters)
                  + " | seeds' range along the ray [share] |", "|---|---|---|---|"]
        for item in sorted(result.rays, key=lambda r: r.ray.angle_deg):
            answer = parameter_boundary(result, item)
            cells = ["beyond the limit" if v is None else f"{v:.4g}"
                     for v in answer["boundary"]]
            low, high = answer["critical_s_range"]
            lines.append(f"| {item.ray.angle_deg:.1f} | " + " | ".join(cells)
                         + f" | {_share(low)}-{_share(high)} |")
    lines += ["", "![envelope](envelope.png)", ""]
    return "\n".join(lines)


def _share(value: float | None) -> str:
    return "beyond" if value is None else f"{value:.3f}"


def write_outputs(result: EnvelopeResult, rows: dict[Any, dict[str, Any]],
                  root: Path) -> list[Path]:
    """``envelope.json``, ``summary.md`` and ``envelope.png`` in ``root``."""
    spec = result.spec
    axis_items = []
    for index in range(len(spec.parameters)):
        for item in result.rays:
            if item.ray.direction[index] > 0 and all(
                    d == 0.0 for j, d in enumerate(item.ray.direction) if j != index):
                axis_items.append((index, item))
    document = {
        "spec": spec.to_dict(), "runs": result.runs,
        "answers": [axis_sentence(result, item, index) for index, item in axis_items],
        "rays": [parameter_boundary(result, item) for item in result.rays],
    }
    json_path = root / "envelope.json"
    json_path.write_text(json.dumps(document, indent=1, default=str) + "\n")
    summary = root / "summary.md"
    summary.write_text(summary_markdown(result, axis_items))
    figure = root / "envelope.png"
    draw(result, rows, figure)
    return [json_path, summary, figure]


def draw(result: EnvelopeResult, rows: dict[Any, dict[str, Any]], path: Path) -> None:
    """One parameter: each seed's robustness against the value, the boundary and the
    margin. Two: every run in the plane (pass or fail), each seed's boundary points, the
    ensemble's boundary through the rays, the nominal point."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from cosim.sweeps.envelope import run_passes

    spec = result.spec
    figure = Figure(figsize=(7.5, 5.4), dpi=120, layout="constrained")
    FigureCanvasAgg(figure)
    axes = figure.add_subplot()
    if len(spec.parameters) == 1:
        _draw_one(axes, result, rows, run_passes)
    else:
        _draw_two(axes, result, rows, run_passes)
    figure.suptitle(f"{spec.name}: {Path(spec.scenario).stem}, {spec.tracker_name}\n"
                    f"requirement {spec.requirement}; boundary: more than "
                    f"{100.0 * spec.failure_rate:g} % of {len(spec.seeds)} seeds fail",
                    fontsize=9)
    figure.savefig(path)


def _draw_one(axes: Any, result: EnvelopeResult, rows: dict[Any, dict[str, Any]],
              run_passes: Any) -> None:
    spec = result.spec
    parameter = spec.parameters[0]
    for seed in spec.seeds:
        points = sorted((key[0][0], run_passes(row)) for key, row in rows.items()
                        if key[1] == seed)
        xs = [x for x, (_, r) in points if math.isfinite(r)]
        ys = [r for _, (_, r) in points if math.isfinite(r)]
        axes.plot(xs, ys, ".-", linewidth=0.6, markersize=4, alpha=0.7)
        stopped = [x for x, (_, r) in points if not math.isfinite(r)]
        axes.plot(stopped, [0.02] * len(stopped), "v", color="tab:red", markersize=5,
                  transform=axes.get_xaxis_transform(), clip_on=False)
    axes.axhline(0.0, color="black", linewidth=1.0)
    axes.axvline(parameter.nominal, color="tab:blue", linestyle=":",
                 label=f"nominal {parameter.nominal:g}")
    (item,) = result.rays
    boundary = result.boundary_s(item)
    if math.isfinite(boundary):
        value = parameter.value(boundary)
        axes.axvline(value, color="tab:red", linestyle="--",
                     label=f"boundary {value:.4g} (margin {value - parameter.nominal:+.4g})")
        axes.axvspan(value, parameter.limit, color="tab:red", alpha=0.07)
    for share in item.critical_shares():
        if math.isfinite(share):
            axes.plot([parameter.value(share)], [0.0], "|", color="tab:red", markersize=12)
    axes.set_xlabel(axis_label(parameter.path))
    axes.set_ylabel("robustness (>= 0: the requirement holds)")
    axes.grid(True, alpha=0.3)
    axes.legend(fontsize=8, title="one line per seed; red v: run stopped (fails)",
                title_fontsize=7)


def _draw_two(axes: Any, result: EnvelopeResult, rows: dict[Any, dict[str, Any]],
              run_passes: Any) -> None:
    spec = result.spec
    px, py = spec.parameters
    good = [key[0] for key, row in rows.items() if run_passes(row)[0]]
    bad = [key[0] for key, row in rows.items() if not run_passes(row)[0]]
    if good:
        axes.plot(*zip(*good, strict=True), "o", color="tab:green", markersize=3, alpha=0.5,
                  label=f"run: pass ({len(good)})")
    if bad:
        axes.plot(*zip(*bad, strict=True), "x", color="tab:red", markersize=4, alpha=0.6,
                  label=f"run: fail ({len(bad)})")
    ordered = sorted(result.rays, key=lambda r: r.ray.angle_deg)
    curve = [_point(spec, item.ray, min(result.boundary_s(item), 1.0)) for item in ordered]
    axes.plot(*zip(*curve, strict=True), "-", color="black", linewidth=1.8,
              label="boundary (ensemble)")
    for item in ordered:
        for share in item.critical_shares():
            if math.isfinite(share):
                axes.plot(*_point(spec, item.ray, share), ".", color="0.4", markersize=2)
    axes.plot([px.nominal], [py.nominal], "*", color="tab:blue", markersize=14,
              label=f"nominal ({px.nominal:g}, {py.nominal:g})")
    axes.plot([px.nominal, px.limit, px.limit, px.nominal, px.nominal],
              [py.nominal, py.nominal, py.limit, py.limit, py.nominal], ":", color="0.5",
              linewidth=0.8, label="search box")
    axes.set_xlabel(axis_label(px.path))
    axes.set_ylabel(axis_label(py.path))
    axes.grid(True, alpha=0.3)
    axes.legend(fontsize=7, loc="best")


def _point(spec: Any, ray: Ray, s: float) -> tuple[float, float]:
    unit = ray.unit_point(s)
    return spec.parameters[0].value(unit[0]), spec.parameters[1].value(unit[1])
