"""Wall time of one scenario in our master, fmpy.ssp and libcosim, side by side in one run.

usage: python bench_masters.py SYSTEM.ssp COSIM_BINARY [--stop T] [--step H] [--repeats N]
Each master runs the same .ssp from its start over the same horizon and step; each time covers
unpacking and loading the FMUs, initialization and stepping (no result file); each master keeps
its best of N interleaved runs."""
import argparse
import os
import re
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(__file__))
from ssp_masters import run_fmpy, run_libcosim  # noqa: E402


def timed(f):
    start = time.perf_counter()
    f()
    return time.perf_counter() - start


def main():
    p = argparse.ArgumentParser()
    p.add_argument("ssp")
    p.add_argument("cosim")
    p.add_argument("--stop", type=float, default=2.0)
    p.add_argument("--step", type=float, default=1e-4)
    p.add_argument("--repeats", type=int, default=3)
    a = p.parse_args()
    signals = ["grid.pcc.f"]

    def ours_once():
        # --no-csv: the Python masters keep one signal in memory and write nothing, so ours
        # streams nothing either (`cargo xtask bench` also times it with every output streamed).
        done = subprocess.run(
            [a.cosim, a.ssp, "--stop", str(a.stop), "--step", str(a.step), "--no-csv"],
            check=True, capture_output=True, text=True)
        found = re.search(r"loaded in ([0-9.]+) s; initialized and simulated \S+ s in ([0-9.]+) s", done.stdout)
        if not found:
            raise SystemExit(f"unexpected cosim output: {done.stdout}")
        return float(found.group(1)) + float(found.group(2))

    # Each master runs REPEATS times, interleaved, and keeps its best time: the machine's speed
    # drifts between runs, and the best run is the one least disturbed.
    times = {"ours": [], "fmpy": [], "libcosim": []}
    for _ in range(a.repeats):
        times["ours"].append(ours_once())
        times["fmpy"].append(timed(lambda: run_fmpy(a.ssp, a.stop, a.step, signals)))
        times["libcosim"].append(timed(lambda: run_libcosim(a.ssp, a.stop, a.step, signals)))
    ours, fmpy, libcosim = (min(times[k]) for k in ("ours", "fmpy", "libcosim"))
    steps = round(a.stop / a.step)
    print(f"{os.path.basename(a.ssp)}: {a.stop} s simulated, {steps} steps of {a.step} s; best of {a.repeats} runs each")
    print("| master | wall time | x real time | our master is faster by |")
    print("|---|---|---|---|")
    for name, t in [("ours (cosim, Jacobi)", ours), ("fmpy.ssp 0.3.32", fmpy), ("libcosim 0.11.2 (libcosimpy 0.0.6)", libcosim)]:
        print(f"| {name} | {t:.3f} s | {a.stop / t:.1f} | {t / ours:.1f}x |")


if __name__ == "__main__":
    main()
