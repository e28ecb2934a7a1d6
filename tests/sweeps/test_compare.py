"""``cosim compare``: the league table from rows, and the command as a user runs it."""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
from collections.abc import Callable
from pathlib import Path

import pytest

from cosim.sweeps.compare import league, make_tasks, markdown
from tests.cli.test_cli import COSIM, cosim
from tests.conftest import Called
from tests.sweeps.rows import wait_for_rows


def _row(run_id: int, scenario: str, tracker: str, seed: int, cte: float,
         error: str = "", failures: int = 0) -> dict:
    return {"run_id": run_id, "seed": seed, "params": {"scenario": scenario, "tracker": tracker},
            "metrics": {"cte_rms_m": cte, "cte_max_m": 3 * cte, "solver_failures": failures},
            "error": error}


def test_league_takes_the_mean_of_rms_and_the_worst_of_maxima_over_seeds() -> None:
    rows = [_row(0, "circle", "pid", 0, 0.1), _row(1, "circle", "pid", 1, 0.3, failures=2),
            _row(2, "circle", "lqr", 0, 0.05, error="PhysicsDivergenceError: boom")]
    table = {r.tracker: r for r in league(rows)}
    assert table["pid"].values["cte_rms_m"] == pytest.approx(0.2)
    assert table["pid"].values["cte_max_m"] == pytest.approx(0.9)
    assert table["pid"].failures == 2
    assert table["lqr"].failures == 1 and table["lqr"].errors == ("PhysicsDivergenceError: boom",)
    text = markdown(list(table.values()))
    assert text.index("| pid |") < text.index("| lqr (1/1 unfinished) |")  # finished first


def test_tasks_cover_every_combination_once() -> None:
    tasks = make_tasks(["circle", "track"], ["pid", "lqr", "ltv-mpc"], 2, 1.0, None)
    keys = {(t.scenario, t.tracker, t.seed) for t in tasks}
    assert len(tasks) == len(keys) == 12
    assert [t.run_id for t in tasks] == list(range(12))


@pytest.mark.slow
def test_compare_runs_every_combination_and_writes_the_table(tmp_path: Path) -> None:
    out = tmp_path / "league"
    result = cosim("compare", "--trackers", "pid,lqr", "--scenarios", "circle",
                   "--duration", "0.5", "--workers", "2", "--json", "--out", str(out))
    assert result.returncode == 0, result.stderr
    rows = json.loads(result.stdout)
    assert {(r["scenario"], r["tracker"], r["seed"]) for r in rows} == {
        ("circle", "pid", 0), ("circle", "lqr", 0)}
    assert all(r["metrics"]["completed"] for r in rows)
    with (out / "league.csv").open() as handle:
        table = list(csv.DictReader(handle))
    assert {r["tracker"] for r in table} == {"pid", "lqr"}
    assert (out / "league.png").stat().st_size > 0
    assert "## circle" in (out / "league.md").read_text()


@pytest.mark.parametrize(("args", "fragment"), [
    (("--trackers", "pid,bogus"), "'bogus' is not one of"),
    (("--trackers", "open-loop"), "'open-loop' is not one of"),
    (("--scenarios", "nowhere"), "scenario 'nowhere'"),
    (("--seeds", "0"), "--seeds 0"),
])
def test_compare_bad_input_is_one_line_and_exit_2(
        tmp_path: Path, args: tuple[str, ...], fragment: str,
        cosim_in_process: Callable[..., Called]) -> None:
    result = cosim_in_process("compare", *args, "--out", str(tmp_path))
    assert result.returncode == 2
    assert fragment in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1


def test_bad_track_csv_is_one_line_and_exit_2(tmp_path: Path) -> None:
    bad = tmp_path / "bad.csv"
    bad.write_text("x,y\n0,0\n1,0\n1,0\n2,2\n")
    result = cosim("run", "track", "--set", f"path.file={bad}", "--out",
                   str(tmp_path / "run.mcap"))
    assert result.returncode == 2
    assert result.stderr.strip() == (f"cosim: error: path.file {str(bad)!r}: data rows 2 and 3 "
                                     "are the same point, expected distinct consecutive points")


@pytest.mark.slow
@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_a_signal_to_compare_alone_stops_its_runs_and_writes_the_league(
        tmp_path: Path, signum: int) -> None:
    """SIGTERM, or a SIGINT sent to the parent only (not a terminal's Ctrl-C, which reaches
    every worker): the run in progress is stopped, not waited for, the league of the
    finished runs is written, and --resume finishes the rest."""
    if signum == signal.SIGINT and signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        # A background job of a non-interactive shell (``make test &`` in a script) starts
        # with SIGINT ignored, and so does every process it starts: the command would
        # rightly ignore it too.
        pytest.skip("SIGINT is ignored in this process, and so in the command it starts")
    out = tmp_path / "league"
    rows_file = out / "rows.jsonl"
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "disable")}
    args = [COSIM, "compare", "--trackers", "pid,lqr,stanley", "--scenarios", "circle",
            "--duration", "40", "--workers", "1", "--out", str(out)]
    # 40 s a run: long enough (a few seconds of wall time) that the signal lands in the
    # second run, not after the third.
    process = subprocess.Popen(args, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               text=True, start_new_session=True)  # no group-wide signal
    try:
        wait_for_rows(process, rows_file)
        process.send_signal(signum)
        _, stderr = process.communicate(timeout=120)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 130, stderr
    rows = [json.loads(line) for line in rows_file.read_text().splitlines()]
    # On a loaded machine the second run may end before the signal is handled; the third
    # is then the one in progress. Either way a run was stopped, not waited for.
    assert len(rows) in (1, 2), "the run in progress was waited for instead of stopped"
    assert stderr.strip().splitlines()[-1] == (
        f"cosim: compare interrupted; the league of the {len(rows)} finished run(s) is in "
        f"{out / 'league.md'}; finish with: cosim compare --resume --out {out}")
    assert "Traceback" not in stderr
    # Each row's run, error and end in full when one did not complete (a row's repr is cut).
    assert all(row["metrics"].get("completed") for row in rows), [
        (row["params"], row["error"], row["interrupted"], row["metrics"].get("outcome"),
         row["metrics"].get("abort_reason")) for row in rows]
    assert rows[0]["params"]["tracker"] in (out / "league.md").read_text()
    again = cosim("compare", "--resume", "--out", str(out))  # as the hint says, no more
    assert again.returncode == 0, again.stderr
    rows = [json.loads(line) for line in rows_file.read_text().splitlines()]
    assert sorted(r["run_id"] for r in rows) == [0, 1, 2]
    league_md = (out / "league.md").read_text()
    assert all(name in league_md for name in ("pid", "lqr", "stanley"))


@pytest.mark.slow
def test_compare_refuses_a_folder_with_results_unless_told(tmp_path: Path) -> None:
    out = tmp_path / "earlier"
    out.mkdir()
    (out / "rows.jsonl").write_text('{"earlier": "row"}\n')
    result = cosim("compare", "--trackers", "pid", "--scenarios", "circle", "--duration",
                   "0.2", "--out", str(out))
    assert result.returncode == 2
    (line,) = result.stderr.strip().splitlines()
    assert "not empty (rows.jsonl)" in line and "--force" in line and "--resume" in line
    assert (out / "rows.jsonl").read_text() == '{"earlier": "row"}\n'
    forced = cosim("compare", "--trackers", "pid", "--scenarios", "circle", "--duration",
                   "0.2", "--out", str(out), "--force")
    assert forced.returncode == 0, forced.stderr
    assert "earlier" not in (out / "rows.jsonl").read_text()


@pytest.mark.slow
def test_a_plugin_that_exits_is_one_failed_row_not_the_end(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``sys.exit`` in a user's tracker: its run is a row with the reason, the others land,
    the league is written (in-process: the pool's workers import ``tests``)."""
    from cosim.cli import main

    out = tmp_path / "league"
    code = main(["compare", "--trackers", "pid,tests.user_trackers:ExitsAtOnce",
                 "--scenarios", "lane-change", "--duration", "0.3", "--workers", "2",
                 "--json", "--out", str(out)])
    assert code == 0, capsys.readouterr().err
    rows = {r["tracker"]: r for r in json.loads(capsys.readouterr().out)}
    assert rows["pid"]["metrics"]["completed"] is True
    exited = rows["tests.user_trackers:ExitsAtOnce"]
    assert exited["metrics"]["completed"] is False
    assert "called sys.exit(\"the user's script gave up\")" in exited["error"]
    assert "tests.user_trackers:ExitsAtOnce" in (out / "league.md").read_text()


def test_the_league_text_fits_any_width_and_cuts_no_number() -> None:
    from cosim.sweeps.compare import LEAGUE_METRICS, LeagueRow, league_text

    values = {key: 1.23456789e-3 * (i + 1) for i, (key, _, _) in enumerate(LEAGUE_METRICS)}
    rows = [LeagueRow("lane-change", name, 1, dict(values), 0, ())
            for name in ("dynamic-nmpc", "pure-pursuit", "lqr", "pid")]
    shown = [f"{v:.4g}" for v in values.values()]
    for width in (None, 200, 90, 40):
        text = league_text(rows, width)
        lines = text.splitlines()
        if width is not None:
            assert max(map(len, lines)) <= width, (width, text)
        assert "…" not in text
        for number in shown:  # every figure whole, for every tracker
            assert text.count(number) == len(rows), (width, number)
    assert len(league_text(rows, None).splitlines()) == 1 + 1 + len(rows)  # a row a tracker


def test_a_tracker_whose_runs_did_not_finish_ranks_below_every_finished_one() -> None:
    """A run cut short has a small RMS CTE over the little it drove: it must not top the
    league; the row says how many of its runs did not finish."""
    from cosim.sweeps.compare import by_scenario, league, markdown

    def row(run_id: int, tracker: str, cte_rms_m: float, error: str = "",
            completed: bool = True) -> dict[str, object]:
        return {"run_id": run_id, "params": {"scenario": "circle", "tracker": tracker},
                "metrics": {"cte_rms_m": cte_rms_m, "completed": completed},
                "error": error}

    rows = [row(0, "my_pkg:Quitter", 0.01, error="called sys.exit(1)", completed=False),
            row(1, "pid", 0.08), row(2, "lqr", 0.05),
            row(3, "stanley", 0.02, completed=False)]
    ranked = [r.tracker for r in by_scenario(league(rows))["circle"]]
    assert ranked == ["lqr", "pid", "my_pkg:Quitter", "stanley"]
    assert "| my_pkg:Quitter (1/1 unfinished) |" in markdown(league(rows))


def test_a_metric_no_run_has_is_left_out_of_the_text_only() -> None:
    """Off the ISO course every tracker's 'gates hit' was '-': two empty columns of 208."""
    from cosim.sweeps.compare import LEAGUE_METRICS, LeagueRow, league_text, markdown

    values = {key: 0.5 for key, _, _ in LEAGUE_METRICS}
    values["gates_hit"] = None
    rows = [LeagueRow("lane-change", name, 1, dict(values), 0, ()) for name in ("a", "b")]
    assert "gates hit" not in league_text(rows, None)
    assert "track exits" in league_text(rows, None)
    assert "gates hit" in markdown(rows)
    rows[1].values["gates_hit"] = 2.0
    assert "gates hit" in league_text(rows, None)
