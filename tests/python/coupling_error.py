"""The coupling error of our master's algorithms on one system, against a fine-step Jacobi run.

Runs the system with Jacobi at a fine step (--reference-step), then Jacobi,
Gauss-Seidel and iterative coupling at --step; prints, per algorithm, the largest and the RMS
difference from the reference at the common communication points of the PCC frequency and
voltage and of each DER slot's active power, the attempts per step (iterative) and the wall
time per macro step (a run without CSV, best of three).

Usage: coupling_error.py SYSTEM.ssp COSIM [--stop 20] [--step 1e-3] [--reference-step 5e-5]
"""

import argparse
import csv
import math
import os
import re
import subprocess
import tempfile


def run(cosim, ssp, stop, step, algorithm, out=None):
    args = [cosim, ssp, "--stop", str(stop), "--step", str(step), "--algorithm", algorithm]
    args += ["--out", out] if out else ["--no-csv"]
    done = subprocess.run(args, check=True, capture_output=True, text=True)
    timing = re.search(r"initialized and simulated \S+ s in ([0-9.]+) s", done.stdout)
    attempts = re.search(r"([0-9.]+) attempts per step", done.stderr)
    return float(timing.group(1)), (float(attempts.group(1)) if attempts else 1.0)


def columns(path, names, every=1):
    with open(path, newline="") as f:
        rows = csv.reader(f)
        header = next(rows)
        idx = [header.index(n) for n in names]
        out = {n: [] for n in names}
        for k, row in enumerate(rows):
            if k % every == 0:
                for n, i in zip(names, idx):
                    out[n].append(float(row[i]))
    return out


def main():
    p = argparse.ArgumentParser()
    p.add_argument("ssp")
    p.add_argument("cosim")
    p.add_argument("--stop", type=float, default=20.0)
    p.add_argument("--step", type=float, default=1e-3)
    p.add_argument("--reference-step", type=float, default=5e-5)
    a = p.parse_args()
    every = round(a.step / a.reference_step)
    with tempfile.TemporaryDirectory() as tmp:
        ref_csv = os.path.join(tmp, "reference.csv")
        run(a.cosim, a.ssp, a.stop, a.reference_step, "jacobi", ref_csv)
        with open(ref_csv, newline="") as f:
            header = next(csv.reader(f))
        names = ["grid.pcc.f", "grid.pcc.v"] + [h for h in header if re.fullmatch(r"grid\.der\[\d+\]\.p", h)]
        ref = columns(ref_csv, names, every)
        print(f"{os.path.basename(a.ssp)}: {a.stop} s at {a.step * 1e3:g} ms against Jacobi at "
              f"{a.reference_step * 1e3:g} ms; largest | RMS difference (pu), wall time per macro step")
        print("| algorithm | " + " | ".join(names) + " | attempts per step | µs per macro step |")
        print("|---" * (len(names) + 3) + "|")
        for algorithm in ("jacobi", "gauss-seidel", "iterative"):
            out = os.path.join(tmp, f"{algorithm}.csv")
            _, attempts = run(a.cosim, a.ssp, a.stop, a.step, algorithm, out)
            got = columns(out, names)
            cells = []
            for n in names:
                d = [x - y for x, y in zip(got[n], ref[n])]
                cells.append(f"{max(abs(x) for x in d):.1e} \\| {math.sqrt(sum(x * x for x in d) / len(d)):.1e}")
            wall = min(run(a.cosim, a.ssp, a.stop, a.step, algorithm)[0] for _ in range(3))
            steps = round(a.stop / a.step)
            print(f"| {algorithm} | " + " | ".join(cells) + f" | {attempts:.2f} | {wall / steps * 1e6:.1f} |")


if __name__ == "__main__":
    main()
