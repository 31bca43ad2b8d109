#!/usr/bin/python3
"""Overhead of the Python binding against the CLI on one remesh job (issue 15: at most 5 %).

Runs, RUNS times each and interleaved, `streamcvd remesh MESH -o OUT -n N` and a fresh python3
process doing `streamcvd.remesh_file(MESH, OUT, N)`; prints the medians of the CLI's wall time,
of the Python process's wall time (interpreter start and import of numpy, ~0.2 s, included) and
of the call alone (what a Python program that already runs and has numpy pays: the overhead), the overheads against the CLI, and whether the
outputs have the same bytes. Also times remesh() on arrays already in memory (no file parse).

Usage: tools/bench_python.py [MESH] [-n N] [--runs R] [--threads T] [--build DIR]
       (default: ../shared/data/stanford_dragon_vrip.ply, N 20000, 5 runs, 1 thread, build)
"""
import argparse
import json
import os
import pathlib
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]

CHILD = r"""
import sys, time, json
t0 = time.monotonic()
import numpy  # what every user of the module has imported already (its results are numpy arrays)
import streamcvd
t1 = time.monotonic()
mode, mesh, out, n, threads = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4]), int(sys.argv[5])
if mode == "file":
    t2, c2 = time.monotonic(), time.process_time()
    streamcvd.remesh_file(mesh, out, n, threads=threads)
    t3, c3 = time.monotonic(), time.process_time()
else:
    m = streamcvd.read(mesh)
    t2, c2 = time.monotonic(), time.process_time()
    streamcvd.remesh(m.points, m.faces, n, threads=threads).write(out)
    t3, c3 = time.monotonic(), time.process_time()
print(json.dumps({"import": t1 - t0, "call": t3 - t2, "call_cpu": c3 - c2}))
"""


def run_timed(command, env=None):
    """Runs `command`; returns (wall seconds, user + system CPU seconds, stdout)."""
    t = time.monotonic()
    child = subprocess.Popen(command, env=env, stdout=subprocess.PIPE, text=True)
    out = child.stdout.read()
    _, status, usage = os.wait4(child.pid, 0)
    child.returncode = os.waitstatus_to_exitcode(status)
    if child.returncode != 0:
        raise SystemExit(f"{command[0]} failed with exit code {child.returncode}")
    return time.monotonic() - t, usage.ru_utime + usage.ru_stime, out


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("mesh", nargs="?", default=str(ROOT.parent / "shared/data/stanford_dragon_vrip.ply"))
    parser.add_argument("-n", type=int, default=20000)
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--build", default=str(ROOT / "build"))
    args = parser.parse_args()
    build = pathlib.Path(args.build).resolve()
    cli = build / "streamcvd"
    env = dict(os.environ, PYTHONPATH=str(build / "python"))
    python = "/usr/bin/python3" if os.path.exists("/usr/bin/python3") else sys.executable
    times = {k: [] for k in ("cli", "cli_cpu", "process", "process_cpu", "call", "call_cpu", "import", "arrays_call")}
    with tempfile.TemporaryDirectory() as tmp:
        out_cli, out_py, out_arrays = (os.path.join(tmp, f"{k}.ply") for k in ("cli", "py", "arrays"))
        for run in range(args.runs):
            # The CLI writes its report too: the binding always builds one.
            wall, cpu, _ = run_timed([str(cli), "remesh", args.mesh, "-o", out_cli, "-n", str(args.n), "--threads",
                                      str(args.threads), "--report", os.path.join(tmp, "cli.json"), "-q"])
            times["cli"].append(wall), times["cli_cpu"].append(cpu)
            wall, cpu, out = run_timed([python, "-c", CHILD, "file", args.mesh, out_py, str(args.n), str(args.threads)],
                                       env=env)
            times["process"].append(wall), times["process_cpu"].append(cpu)
            inner = json.loads(out)
            times["call"].append(inner["call"])
            times["call_cpu"].append(inner["call_cpu"])
            times["import"].append(inner["import"])
            _, _, out = run_timed([python, "-c", CHILD, "arrays", args.mesh, out_arrays, str(args.n), str(args.threads)],
                                  env=env)
            times["arrays_call"].append(json.loads(out)["call"])
            print(f"run {run + 1}: cli {times['cli'][-1]:.3f} s ({times['cli_cpu'][-1]:.3f} s CPU), python process "
                  f"{times['process'][-1]:.3f} s ({times['process_cpu'][-1]:.3f} s CPU), remesh_file call "
                  f"{times['call'][-1]:.3f} s, remesh(arrays)+write {times['arrays_call'][-1]:.3f} s", file=sys.stderr)
        same = [pathlib.Path(p).read_bytes() == pathlib.Path(out_cli).read_bytes() for p in (out_py, out_arrays)]
    med = {k: statistics.median(v) for k, v in times.items()}
    print(f"{args.mesh} -> {args.n}, threads {args.threads}, medians of {args.runs} runs (load {os.getloadavg()[0]:.2f}):")
    print(f"  CLI wall                         {med['cli']:.3f} s  (CPU {med['cli_cpu']:.3f} s)")
    print(f"  python process wall              {med['process']:.3f} s  ({100 * (med['process'] / med['cli'] - 1):+.1f} %,"
          f" import numpy + streamcvd {med['import']:.3f} s; CPU {med['process_cpu']:.3f} s, "
          f"{100 * (med['process_cpu'] / med['cli_cpu'] - 1):+.1f} %)")
    print(f"  remesh_file() call               {med['call']:.3f} s  ({100 * (med['call'] / med['cli'] - 1):+.1f} %; "
          f"CPU {med['call_cpu']:.3f} s, {100 * (med['call_cpu'] / med['cli_cpu'] - 1):+.1f} %)")
    print(f"  remesh(arrays) + write, no parse {med['arrays_call']:.3f} s  ({100 * (med['arrays_call'] / med['cli'] - 1):+.1f} %)")
    print(f"  same bytes as the CLI: remesh_file {same[0]}, remesh(arrays) {same[1]}"
          + ("" if args.threads == 1 else " (only expected with --threads 1)"))


if __name__ == "__main__":
    main()
