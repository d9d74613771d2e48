"""``mavreg experiment``: bad input is one line and exit 2; --help names what exists."""
from __future__ import annotations

import pytest

from mavreg.cli.main import main


@pytest.mark.parametrize("argv, needle", [
    (["wind"], "unknown experiment 'wind'; choose one of paper-group1, paper-group2, gust, lag"),
    (["lag", "--via", "sitl"], "lag flies only on the design model"),
    (["gust", "--dask", "tcp://127.0.0.1:1", "--jobs", "2"], "--jobs sizes the local process pool"),
    (["paper-group1", "--jobs", "0"], "--jobs must be at least 1, got 0"),
    (["paper-group1", "--jobs", "two"], "--jobs must be a whole number, got 'two'"),
    (["paper-group1", "--seed", "-3"], "--seed must be at least 0, got -3"),
    (["paper-group1", "--via", "hardware"], "--via must be one of sim, sitl, got 'hardware'"),
    (["paper-group2", "--keep-flight-files"], "--keep-flight-files applies only to --via sitl"),
])
def test_bad_input_is_one_line_and_exit_2(argv, needle, capsys, tmp_path):
    code = main(["experiment", *argv, "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2
    assert err.strip().count("\n") == 0 and needle in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()          # nothing was started


def test_an_out_that_is_a_file_is_one_line_and_exit_2(capsys, tmp_path):
    f = tmp_path / "a_file"
    f.write_text("")
    assert main(["experiment", "paper-group1", "--out", str(f)]) == 2
    err = capsys.readouterr().err
    assert err.strip().count("\n") == 0 and f"--out {f}" in err


def test_help_names_the_experiments_and_the_options(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["experiment", "--help"])
    out = capsys.readouterr().out
    assert exc.value.code == 0
    for name in ("paper-group1", "paper-group2", "gust", "lag", "--via", "--jobs", "--dask"):
        assert name in out
