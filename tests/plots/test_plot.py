"""`cosim plot`: every figure is written, is not blank, and overlays two runs; the data the
figures draw agree with the run's own metrics; bad files are one line and exit code 2."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from cosim.cli import main
from cosim.core.exceptions import CosimError
from cosim.plots import FIGURES, plot_logs
from cosim.plots.data import distinct_labels, load_run
from cosim.simulation.runner import RunResult, run
from cosim.simulation.scenario_config import load_config

EXPECTED = (*FIGURES[:FIGURES.index("estimation") + 1], "estimation_internal",
            *FIGURES[FIGURES.index("estimation") + 1:])
"""The PNGs of a run with the EKF: its biases and scales have a figure of their own."""

MIN_PNG_BYTES = 40_000
"""A figure with axes, lines and text at 130 dpi is well above this; a blank one is not."""


@pytest.fixture(scope="module")
def nmpc_run(tmp_path_factory: pytest.TempPathFactory) -> RunResult:
    """Three seconds of the lane change with the default tracker (plans with x_m, y_m)."""
    config = load_config("lane-change", duration_s=3.0)
    return run(config, tmp_path_factory.mktemp("plot") / "nmpc.mcap")


@pytest.fixture(scope="module")
def path_error_run(tmp_path_factory: pytest.TempPathFactory) -> RunResult:
    """dynamic-mpc: its plans predict path errors (e1_m, ...), no world-frame x_m, y_m."""
    config = load_config("lane-change", duration_s=3.0, tracker="dynamic-mpc")
    return run(config, tmp_path_factory.mktemp("plot") / "dmpc.mcap")


def _assert_real_figure(path: Path) -> None:
    from matplotlib.image import imread

    assert path.is_file(), path
    assert path.stat().st_size > MIN_PNG_BYTES, (path, path.stat().st_size)
    pixels = imread(path)
    assert pixels.ndim == 3 and pixels.shape[0] > 500 and pixels.shape[1] > 500
    # Not blank: many distinct grey levels and a real spread of them.
    grey = pixels[..., :3].mean(axis=2)
    assert float(grey.var()) > 1e-3, path
    assert np.unique(np.round(grey, 2)).size > 20, path


@pytest.mark.slow
def test_every_figure_of_one_run(nmpc_run: RunResult, tmp_path: Path) -> None:
    written = plot_logs([nmpc_run.log_path], tmp_path / "one")
    assert [p.name for p in written] == [f"{name}.png" for name in EXPECTED]
    for path in written:
        _assert_real_figure(path)
    # Drawn by one process alone, every figure is the same file (two drew the above where
    # there are two cores: cosim.plots.drawing).
    alone = plot_logs([nmpc_run.log_path], tmp_path / "alone", processes=1)
    for path, same in zip(written, alone, strict=True):
        assert path.read_bytes() == same.read_bytes(), path.name


@pytest.mark.slow
def test_overlay_of_two_trackers(
        nmpc_run: RunResult, path_error_run: RunResult, tmp_path: Path) -> None:
    single = plot_logs([nmpc_run.log_path], tmp_path / "single")
    overlay = plot_logs([nmpc_run.log_path, path_error_run.log_path], tmp_path / "overlay")
    assert [p.name for p in overlay] == [p.name for p in single]
    for alone, both in zip(single, overlay, strict=True):
        _assert_real_figure(both)
        assert alone.read_bytes() != both.read_bytes(), both.name
    runs = distinct_labels([load_run(nmpc_run.log_path), load_run(path_error_run.log_path)])
    assert [r.label for r in runs] == ["lane-change / dynamic-nmpc", "lane-change / dynamic-mpc"]
    assert runs[0].plans is not None and runs[0].plans.has_positions
    # dynamic-mpc predicts path errors and adds the world positions they stand for.
    assert runs[1].plans is not None and runs[1].plans.has_positions
    assert "e1_m" in runs[1].plans.state_names


@pytest.mark.slow
def test_three_runs_overlay_and_too_many_are_refused(
        nmpc_run: RunResult, path_error_run: RunResult, tmp_path: Path) -> None:
    from cosim.plots import MAX_LOGS
    from cosim.plots.style import run_colour

    logs = [nmpc_run.log_path, path_error_run.log_path, nmpc_run.log_path]
    written = plot_logs(logs, tmp_path / "three")
    two = plot_logs(logs[:2], tmp_path / "two")
    for three_runs, two_runs in zip(written, two, strict=True):
        _assert_real_figure(three_runs)
        assert three_runs.read_bytes() != two_runs.read_bytes(), three_runs.name
    assert len({run_colour(i) for i in range(MAX_LOGS)}) == MAX_LOGS  # each its colour
    with pytest.raises(CosimError, match=f"expected one log, or up to {MAX_LOGS}"):
        plot_logs([nmpc_run.log_path] * (MAX_LOGS + 1), tmp_path / "many")


def test_overlay_labels_name_every_difference_the_mismatch_first(nmpc_run: RunResult) -> None:
    """Five keys differ: all are named (never "+n more": the hidden one could be the
    cause), the plant and belief keys first; a belief told the plant's value shows as the
    request with its value."""
    from dataclasses import replace

    base = load_run(nmpc_run.log_path)
    config = {**base.config,
              "tracker": {**base.config["tracker"], "horizon": 31, "latency_s": 0.1,
                          "latency_compensation": False, "weights": {
                              **base.config["tracker"]["weights"], "cte": 77.0}},
              "plant": {**base.config["plant"], "actuator_delay_s": 0.1},
              "beliefs_from_plant": {"tracker.latency_s": "plant.actuator_delay_s"}}
    other = replace(base, config=config)
    labels = [r.label for r in distinct_labels([base, other])]
    assert "more" not in " ".join(labels)
    assert labels[1].startswith("lane-change / dynamic-nmpc: plant.actuator_delay_s=0.1, "
                                "tracker.latency_s=plant (0.1)")
    for key in ("tracker.horizon=31", "tracker.latency_compensation=false",
                "tracker.weights.cte=77"):
        assert key in labels[1], labels[1]
    assert "tracker.latency_s=0," in labels[0]


def test_overlaid_runs_are_named_by_their_difference_and_told_apart_by_style(
        nmpc_run: RunResult) -> None:
    from dataclasses import replace

    from cosim.plots.style import RUN_COLOURS
    from cosim.plots.top_view import top_view

    base = load_run(nmpc_run.log_path)
    heavy_config = {**base.config, "plant": {**base.config["plant"], "mass_kg": 2000.0}}
    heavy = replace(base, config=heavy_config)
    runs = distinct_labels([base, heavy])
    assert [r.label for r in runs] == ["lane-change / dynamic-nmpc: plant.mass_kg=1575",
                                       "lane-change / dynamic-nmpc: plant.mass_kg=2000"]
    # The same configuration twice: named by file, else numbered.
    assert [r.label for r in distinct_labels([base, base])] == [
        "run 1: lane-change / dynamic-nmpc", "run 2: lane-change / dynamic-nmpc"]
    # Three runs, two of them alike: the difference still names them, the file tells the
    # two alike apart.
    twin = replace(base, path=base.path.with_name("twin.mcap"))
    assert [r.label for r in distinct_labels([base, twin, heavy])] == [
        "lane-change / dynamic-nmpc: plant.mass_kg=1575 (nmpc)",
        "lane-change / dynamic-nmpc: plant.mass_kg=1575 (twin)",
        "lane-change / dynamic-nmpc: plant.mass_kg=2000"]
    figure = top_view(runs)
    for ax in figure.axes:
        styles = {colour: {str(line.get_linestyle()) for line in ax.get_lines()
                           if line.get_color() == colour and len(line.get_xdata()) > 20
                           and line.get_linewidth() >= 1.2}  # paths, not footprints
                  for colour in RUN_COLOURS}
        if styles[RUN_COLOURS[0]] and styles[RUN_COLOURS[1]]:
            assert "-" in styles[RUN_COLOURS[0]]
            assert "-" not in styles[RUN_COLOURS[1]], ax.get_title()


@pytest.mark.slow
def test_a_spin_is_plotted_as_a_spin(tmp_path: Path) -> None:
    """On a slippery road the car spins metres off the path: the deviation panel's range
    covers the whole CTE (not a band of centimetres), on both sides."""
    from cosim.plots.top_view import DEVIATION_TITLE, top_view

    config = load_config("lane-change", duration_s=10.0,  # on after the spin, metres off
                         overrides=["plant.tyre_friction=0.3", "outcome.keep_going=true"])
    result = run(config, tmp_path / "spin.mcap")
    data = load_run(result.log_path)
    assert data.tracking is not None
    cte_cm = data.tracking.cte_m * 100.0
    assert np.max(np.abs(cte_cm)) > 300.0  # it did leave the path by metres
    (deviation,) = [ax for ax in top_view([data]).axes
                    if ax.get_title().startswith(DEVIATION_TITLE)]
    low, high = deviation.get_ylim()
    x_low, x_high = deviation.get_xlim()
    worst = int(np.argmax(np.abs(cte_cm)))
    assert x_low <= data.truth.x_m[worst] <= x_high
    shown = (data.truth.x_m >= x_low) & (data.truth.x_m <= x_high)
    assert low <= np.min(cte_cm[shown]) and np.max(cte_cm[shown]) <= high
    assert low <= -abs(cte_cm[worst]) or high >= abs(cte_cm[worst])
    assert high - low >= np.max(np.abs(cte_cm))
    for path in plot_logs([result.log_path], tmp_path / "plots"):
        _assert_real_figure(path)


def test_the_plotted_errors_are_the_metrics(nmpc_run: RunResult) -> None:
    """CTE by projection and NEES per sample, recomputed from the log, give the metrics."""
    data = load_run(nmpc_run.log_path)
    metrics = nmpc_run.metrics
    assert data.tracking is not None and data.estimation is not None
    assert float(np.max(np.abs(data.tracking.cte_m))) == pytest.approx(
        metrics["cte_max_m"], rel=0.02, abs=1e-3)
    heading_rms = float(np.sqrt(np.mean(data.tracking.heading_err_rad**2)))
    assert heading_rms == pytest.approx(metrics["heading_err_rms_rad"], rel=0.02)
    assert data.estimation.nees is not None
    assert data.estimation.nees_states == ("x_m", "y_m", "yaw_rad", "vx_mps")
    assert float(np.nanmean(data.estimation.nees)) == pytest.approx(metrics["nees_mean"],
                                                                    rel=1e-6)
    assert data.truth.t_s.size == data.estimation.t_s.size == 301


def test_the_imu_biases_are_drawn_against_their_truth(nmpc_run: RunResult) -> None:
    """The truth carries the IMU's own biases, so each bias estimate is drawn as an error:
    after the first second the EKF's error stays inside its 3 sigma almost always (a bias
    logged with the wrong sign or channel would be twice the bias, far outside)."""
    data = load_run(nmpc_run.log_path)
    assert data.estimation is not None
    settled = data.estimation.t_s >= 1.0
    for name in ("gyro_bias_radps", "ax_bias_mps2", "ay_bias_mps2"):
        truth = getattr(data.truth, name)
        assert np.all(np.isfinite(truth)) and np.any(truth != 0.0), name
        error = data.estimation.error[name][settled]
        sigma = data.estimation.sigma[name][settled]
        assert np.mean(np.abs(error) <= 3.0 * sigma) > 0.95, name


@pytest.mark.slow
def test_a_truncated_log_is_plotted_and_marked(nmpc_run: RunResult, tmp_path: Path) -> None:
    content = nmpc_run.log_path.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(content[: len(content) * 2 // 3])
    data = load_run(cut)
    assert data.truncated and data.metrics is None
    assert 0 < data.truth.t_s.size < 301
    for path in plot_logs([cut], tmp_path / "cut"):
        _assert_real_figure(path)


@pytest.mark.slow
def test_cli_prints_the_paths(nmpc_run: RunResult, tmp_path: Path,
                              capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "cli"
    assert main(["plot", str(nmpc_run.log_path), "--out", str(out)]) == 0
    printed = capsys.readouterr().out.split()
    assert printed == [str(out / f"{name}.png") for name in EXPECTED]


@pytest.mark.parametrize(("content", "fragment"), [
    (None, "no such file"),
    (b"hello", "not an MCAP file"),
    (b"\x89MCAP0\r\n" + b"\x00" * 40, "MCAP"),
])
def test_bad_files_are_one_line_and_exit_code_2(
        content: bytes | None, fragment: str, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "bad.mcap"
    if content is not None:
        path.write_bytes(content)
    assert main(["plot", str(path)]) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and fragment in lines[0], captured.err
    assert captured.out == ""


def test_labels_name_overlaid_logs_one_each(nmpc_run: RunResult, tmp_path: Path,
                                            monkeypatch: pytest.MonkeyPatch) -> None:
    import cosim.plots.tracking as tracking

    log = nmpc_run.log_path
    with pytest.raises(CosimError, match=r"--label given 1 time\(s\) for 2 log\(s\)"):
        plot_logs([log, log], tmp_path, labels=["only one"])
    with pytest.raises(CosimError, match="a different label for each log"):
        plot_logs([log, log], tmp_path, labels=["same", "same"])
    seen: list[list[str]] = []
    real = tracking.tracking_figure
    monkeypatch.setattr(tracking, "tracking_figure",
                        lambda runs, path: (seen.append([r.label for r in runs]),
                                            real(runs, path))[1])
    plot_logs([log, log], tmp_path, labels=["before", "after"])
    assert seen == [["before", "after"]]


def test_a_circuit_is_drawn_whole_and_its_deviation_along_the_lap(tmp_path: Path) -> None:
    """A closed path's x folds its straights onto each other: the deviation is drawn
    against the distance along the lap instead."""
    from cosim.plots.top_view import top_view

    result = run(load_config("track", duration_s=3.0), tmp_path / "track.mcap")
    figure = top_view([load_run(result.log_path)])
    labels = [ax.get_xlabel() for ax in figure.axes]
    assert any(label.startswith("distance along the path s [m]") for label in labels)
    assert not any(ax.get_title().startswith("the manoeuvre, lateral axis stretched")
                   for ax in figure.axes)


def test_a_figure_is_laid_out_once_and_saved_as_savefig_saves_it(
        nmpc_run: RunResult, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """cosim.plots.style.save draws a figure once (savefig draws a laid-out figure twice)
    and writes the bytes savefig writes."""
    from matplotlib.figure import Figure

    from cosim.plots.style import save
    from cosim.plots.top_view import top_view

    runs = [load_run(nmpc_run.log_path)]
    ours, reference = top_view(runs), top_view(runs)
    draws: list[int] = []
    draw = Figure.draw

    def counted(figure: Figure, renderer: object) -> None:
        draws.append(1)
        draw(figure, renderer)

    monkeypatch.setattr(Figure, "draw", counted)
    written = save(ours, tmp_path / "ours.png")
    assert len(draws) == 1
    reference.savefig(tmp_path / "savefig.png", dpi=reference.dpi)
    assert len(draws) == 3
    assert written.read_bytes() == (tmp_path / "savefig.png").read_bytes()
