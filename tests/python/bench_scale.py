"""Our master and libcosim side by side on systems of N units (the scale benchmark's systems).

Usage: bench_scale.py DIR COSIM UNIT_STEPS

DIR holds one SSP directory per N (``nN/``, written by the scale benchmark: N components of the
default DER FMU, no connections, every output recorded). For each N both masters run the same
system for max(200, UNIT_STEPS / N) steps of 1 ms (ours at least 2000), three times,
interleaved; the best time of each counts. Ours runs on one thread and on two (`--threads`);
libcosim with its defaults. Timed: stepping (and sampling every output), per macro step. Not
timed: reading the system, loading the FMUs, initialization. Ours: the `µs per step after
initialization` it prints (the time from the end of initialization to the last sample). libcosim: ``simulate_until`` from
the end of the first step (libcosim initializes in it) with a last-value observer, which reads
every output as ours records every output.
"""
import pathlib
import re
import subprocess
import sys
import time

REPS = 3
STEP = 1e-3
# Least number of steps of our runs.
OURS_MIN_STEPS = 2000


def ours(cosim, system, steps, threads):
    """µs per macro step after initialization, as our master reports it."""
    out = subprocess.run([cosim, str(system), "--stop", str(steps * STEP), "--step", str(STEP),
                          "--threads", str(threads), "--no-csv"],
                         check=True, capture_output=True, text=True).stdout
    m = re.search(r"([0-9.e+-]+) µs per step after initialization", out)
    if not m:
        raise RuntimeError(f"cannot read our run's time from: {out[-400:]}")
    return float(m.group(1))


def libcosim(system, steps):
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver

    log_output_level(CosimLogLevel.ERROR)
    execution = CosimExecution.from_ssp_file(str(system), step_size=int(STEP * 1e9))
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer=observer)
    ns = int(round(STEP * 1e9))
    if not execution.simulate_until(target_time=ns):
        raise RuntimeError(f"libcosim failed on {system}")
    started = time.perf_counter()
    if not execution.simulate_until(target_time=(steps + 1) * ns):
        raise RuntimeError(f"libcosim failed on {system}")
    return time.perf_counter() - started


def main():
    root, cosim, unit_steps = pathlib.Path(sys.argv[1]), sys.argv[2], int(sys.argv[3])
    systems = sorted(((int(p.name[1:]), p) for p in root.glob("n*") if p.name[1:].isdigit()))
    print()
    print(f"scale: our master and libcosim on the same systems ({REPS} runs each, interleaved, best)")
    print("| N | steps: ours / libcosim | ours, 1 thread: µs per macro step | ours, 2 threads | "
          "libcosim: µs per macro step | ours faster by: 1 thread | 2 threads |")
    print("|---|---|---|---|---|---|---|")
    for n, system in systems:
        steps = max(200, unit_steps // n)
        k = max(steps, OURS_MIN_STEPS)
        runs = {1: [], 2: []}
        b = []
        for _ in range(REPS):
            for threads, times in runs.items():
                times.append(ours(cosim, system, k, threads))
            b.append(libcosim(system, steps))
        us = {t: min(times) for t, times in runs.items()}
        us_b = min(b) / steps * 1e6
        print(f"| {n} | {k} / {steps} | {us[1]:.1f} | {us[2]:.1f} | {us_b:.1f} | "
              f"{us_b / us[1]:.1f}× | {us_b / us[2]:.1f}× |", flush=True)


if __name__ == "__main__":
    main()
