"""``make bench``: run every benchmark and write BENCHMARKS.md (machine, command, date, tables).

Each benchmark runs in its own process, one after the other. Set BENCH_ONLY=core,vanet to run a subset
(the other sections of BENCHMARKS.md are kept as they were).
"""

from __future__ import annotations

import datetime
import os
import platform
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "BENCHMARKS.md"
BENCHES = [
    (
        "headline",
        "The headline: `cosim run` (everything on) vs the `sumo` binary on the same scenario (issue 20)",
        ["bench.bench_headline", "--seconds", "120", "--repeat", "3"],
    ),
    (
        "sumo_step",
        "SUMO's own step: the binary, libsumo, and libsumo inside cosim (issue 20 item 2)",
        ["bench.bench_sumo_step"],
    ),
    (
        "kernels",
        "Compiled kernels: `cosim run` with and without the numba line-of-sight kernels (issue 20 item 4)",
        ["bench.bench_kernels", "--seconds", "120", "--repeat", "3"],
    ),
    ("scenario", "Scenario build: cold vs cached (issue: scenario pipeline)", ["bench.bench_scenario"]),
    (
        "core",
        "Core loop vs bare SUMO on Helsinki (issues: core, VANET, ego)",
        ["bench.bench_core", "--seconds", "60", "--repeat", "2"],
    ),
    ("vanet", "VANET layer alone, synthetic traffic on Helsinki roads (issue: VANET)", ["bench.bench_vanet"]),
    ("radio", "cosim radio cost per simulated second (issue 17)", ["bench.bench_radio"]),
    (
        "mac",
        "MAC cost per simulated second: SOTDMA, IEEE 802.11p, C-V2X mode 4 (issue 18)",
        ["bench.bench_mac"],
    ),
    ("ego", "MuJoCo ego cost (issue: ego)", ["bench.bench_ego"]),
    (
        "experiment",
        "make experiment: the paper's protocol, 4 x 15 min (issue: experiment)",
        ["bench.bench_experiment", "--repeat", "3"],
    ),
    (
        "drive",
        "The driving task on every real map: drive health of 300-s default runs and of the experiment (issue 15)",
        ["bench.bench_drive", "--experiment"],
    ),
    (
        "traffic",
        "Background traffic in plain SUMO: collisions and teleports over 10 SUMO seeds per map (issue 15 item 5)",
        ["bench.bench_traffic"],
    ),
    ("sweep", "Sweep throughput, local pool vs Ray (issue: sweeps)", ["bench.bench_sweep"]),
    (
        "render",
        "3D view frame rate and input-to-display latency (issues: 3D view, 20 item 6)",
        ["bench.bench_render", "--seconds", "20", "--repeat", "3"],
    ),
]


def machine() -> str:
    cpu = next((ln.split(":", 1)[1].strip() for ln in Path("/proc/cpuinfo").read_text().splitlines()
                if ln.startswith("model name")), platform.processor())  # fmt: skip
    mem = next(
        (ln.split()[1] for ln in Path("/proc/meminfo").read_text().splitlines() if ln.startswith("MemTotal")),
        "?",
    )
    return f"{cpu}, {os.cpu_count()} cores, {int(mem) // 1024 // 1024} GiB, {platform.platform()}, Python {platform.python_version()}"


def sections(text: str) -> dict[str, str]:
    return {
        m.group(1): m.group(0) for m in re.finditer(r"<!-- bench:(\w+) -->.*?<!-- /bench:\1 -->", text, re.S)
    }


def main() -> None:
    only = set(filter(None, os.environ.get("BENCH_ONLY", "").split(",")))
    old = sections(OUT.read_text()) if OUT.exists() else {}
    parts = []
    for key, title, cmd in BENCHES:
        if only and key not in only:
            if key in old:
                parts.append(old[key])
            continue
        if not (ROOT / "bench" / f"{cmd[0].split('.')[-1]}.py").exists():
            continue
        print(f"== {key}: python -m {' '.join(cmd)}", flush=True)
        started = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC")
        proc = subprocess.run([sys.executable, "-m", *cmd], cwd=ROOT, capture_output=True, text=True)
        # (TraCI's client prints "Retrying in 1 seconds" while SUMO starts: not a result)
        out = "\n".join(ln for ln in proc.stdout.splitlines() if not ln.strip().startswith("Retrying in"))
        body = (
            out.strip()
            if proc.returncode == 0
            else f"FAILED (exit {proc.returncode}):\n```\n{proc.stderr[-2000:]}\n```"
        )
        print(body, flush=True)
        load = os.getloadavg()[0]
        parts.append(f"<!-- bench:{key} -->\n## {title}\n\n`python -m {' '.join(cmd)}` — {started}, load average "
                     f"{load:.1f} after the run\n\n{body}\n<!-- /bench:{key} -->")  # fmt: skip
    header = (
        f"# Benchmarks\n\nMachine: {machine()}.\nWritten by `make bench` (bench/run_all.py); every "
        "number is wall time on this shared machine, ratios are measured within one run of a benchmark.\n"
    )
    OUT.write_text(header + "\n" + "\n\n".join(parts) + "\n")
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
