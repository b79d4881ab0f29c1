"""Result files as a user reads them: the .mat file in scipy equal to the CSV to the last bit, a
chosen record set and output interval, and an interrupted run's readable .mat.partial."""
import csv
import os
import pathlib
import signal
import subprocess
import time

import numpy as np
import pytest
from scipy.io import loadmat

from conftest import DIST

COSIM = os.environ.get("DVPP_COSIM", str(pathlib.Path(__file__).parents[2] / "target" / "release" / "cosim"))


def case1():
    path = DIST.parent / "case1_load" / "case1_load.ssp"
    if not path.exists():
        pytest.skip(f"{path} not bundled (run cargo xtask bundle)")
    return path


def read_mat(path):
    """The reader of docs/results.md: column names and one row per communication point."""
    m = loadmat(path, chars_as_strings=False)
    names = ["".join(c).rstrip() for c in m["name"].T]
    return names, m["data_2"].T


def read_csv(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], np.array([[float(x) for x in r] for r in rows[1:]])


def cosim(*args):
    return subprocess.run([COSIM, *map(str, args)], check=True, capture_output=True, text=True)


def test_the_mat_file_equals_the_csv_to_the_last_bit(tmp_path):
    ssp = case1()
    for record in ["all", None]:
        extra = ["--record", record] if record else []
        cosim(ssp, "--stop", 2, "--out", tmp_path / "r.csv", *extra)
        cosim(ssp, "--stop", 2, "--out", tmp_path / "r.mat", *extra)
        names_csv, csv_data = read_csv(tmp_path / "r.csv")
        names_mat, mat_data = read_mat(tmp_path / "r.mat")
        assert names_mat == names_csv
        assert mat_data.shape == csv_data.shape == (2001, len(names_csv))
        assert np.array_equal(mat_data.view(np.uint64), csv_data.view(np.uint64))
        if record is None:
            # The scenario's default set: what the case-study figure plots, not every output.
            assert "grid.pcc.f" in names_csv and "operator.ref.df" in names_csv
            assert "wind.energy.loss" not in names_csv and len(names_csv) < 40


def test_a_chosen_record_set_at_an_output_interval(tmp_path):
    ssp = case1()
    out = tmp_path / "r.mat"
    cosim(ssp, "--stop", 2, "--out", out, "--record", "grid.pcc.*,*.v_dc", "--output-interval", 0.01)
    names, data = read_mat(out)
    assert names == ["time", "grid.pcc.p", "grid.pcc.q", "grid.pcc.v", "grid.pcc.f",
                     "wind.v_dc", "pv.v_dc", "bess.v_dc"]
    # Every 10th communication point of 1 ms, exactly on the grid of points.
    assert np.array_equal(data[:, 0], np.round(np.arange(201) * 0.01, 12))
    bad = subprocess.run([COSIM, ssp, "--stop", "0.1", "--out", tmp_path / "x.mat",
                          "--record", "nosuch.*"], capture_output=True, text=True)
    assert bad.returncode != 0 and "'nosuch.*' matches no output" in bad.stderr
    bad = subprocess.run([COSIM, ssp, "--stop", "0.1", "--out", tmp_path / "x.mat",
                          "--output-interval", "0.0015"], capture_output=True, text=True)
    assert bad.returncode != 0 and "not a whole multiple" in bad.stderr


def test_an_interrupted_run_leaves_a_readable_partial_mat_file(tmp_path):
    ssp = case1()
    out = tmp_path / "r.mat"
    run = subprocess.Popen([COSIM, ssp, "--stop", "200", "--step", "1e-4", "--out", out, "--record", "all"],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    partial = pathlib.Path(str(out) + ".partial")
    deadline = time.time() + 60
    while not (partial.exists() and partial.stat().st_size > 1 << 20):
        assert run.poll() is None and time.time() < deadline, run.stderr.read() if run.poll() else "no rows"
        time.sleep(0.05)
    run.send_signal(signal.SIGINT)
    _, err = run.communicate(timeout=60)
    assert run.returncode == 128 + signal.SIGINT, err
    assert not out.exists()
    names, data = read_mat(partial)
    assert len(names) == data.shape[1] and data.shape[0] > 100
    t = data[:, 0]
    assert np.all(np.diff(t) > 0) and t[0] == 0.0
    assert f"{data.shape[0]} complete rows" in err, err
