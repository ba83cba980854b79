"""The ``cosim`` command: parses arguments and calls the library. User errors -> one line, exit code 2."""

from __future__ import annotations

import argparse
import errno
import json
import math
import os
import signal
import sys
from pathlib import Path

from cosim.config import check_seed
from cosim.errors import ConfigError, CosimError, require_display
from cosim.outdir import RunDir, check_dir, check_file


class _Parser(argparse.ArgumentParser):
    """argparse with its errors as one line (no usage block), exit code 2 like every other user error."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _seed(text: str) -> int:
    try:
        return check_seed(int(text), "--seed")
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    except ConfigError as exc:
        raise argparse.ArgumentTypeError(exc.problem) from None


def _seconds(text: str) -> float:
    """A positive, finite number of seconds."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of seconds, got {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be a finite number of seconds > 0, got {text}")
    return value


def _terminated(signum, frame):
    """SIGTERM ends a run like Ctrl-C: the loop stops, the log is closed, the summary printed."""
    global _signal_exit
    _signal_exit = 128 + signum
    raise KeyboardInterrupt


_signal_exit = 130


def _build_scenario(args) -> int:
    from cosim.scenario import build_scenario

    if args.out:
        check_dir(args.out)
    scn = build_scenario(args.osm, args.out, density=args.density, seed=args.seed)
    if args.check:
        from cosim.scenario.check import check_scenario

        c = check_scenario(scn.dir, args.check)
        print(f"  check: {c['duration_s']:.0f} s of traffic in SUMO: {c['departed']} departed, {c['arrived']} arrived, "
              f"{c['mean_vehicles']:.0f} on the road on average (max {c['max_vehicles']}), {c['teleports']} teleports "
              f"({100 * c['teleport_share']:.1f} % of departures), {c['collisions']} collisions; {c['wall_s']:.0f} s wall")  # fmt: skip
    return 0


def _run(args) -> int:
    from cosim.runconfig import load_run_config
    from cosim.sim import Simulation

    overrides = {"scenario.map": args.map, "scenario.demand.density": args.density, "duration_s": args.duration,
                 "seed": args.seed}  # fmt: skip
    config = load_run_config(args.config, **overrides)
    if (
        config.ego.enabled
        and config.ego.physics == "mujoco"
        and config.ego.driver.kind in ("keyboard", "wheel")
    ):
        raise CosimError(f"ego.driver.kind: {config.ego.driver.kind} is a person driving: use `cosim drive` (a window "
                         f"for the driver's view and input), or kind: scripted for `cosim run`")  # fmt: skip
    if args.gui:
        require_display("--gui (sumo-gui)")
    out = Path(args.out) if args.out else Path("results") / config.name
    say = None if not args.quiet else (lambda *a: None)
    with RunDir(out, force=args.force):
        with Simulation(
            config, out_dir=out, gui=args.gui, quiet=args.quiet, log=say, radio_process=None
        ) as sim:
            stats = sim.run()
    stats["log"] = str(out / "run.mcap")
    print(json.dumps(stats) if args.quiet else "\n".join(f"{k}: {v}" for k, v in stats.items()))
    health = stats["health"]
    if health["status"] != "ok":  # the run's numbers stand on a drive that did not happen as planned
        print(f"cosim: warning: degraded drive: {'; '.join(health['problems'])}", file=sys.stderr)
    return _signal_exit if stats["interrupted"] else 0


def _log_info(args) -> int:
    from cosim.log import read

    log = read(args.file, topics=[])
    print(f"{args.file}: {sum(log.counts.values())} messages, {log.duration_s:.1f} s"
          + (" (truncated: read up to the last complete chunk)" if log.truncated else ""))  # fmt: skip
    for topic, n in sorted(log.counts.items()):
        print(f"  {topic:<24} {n:>8} messages")
    for name, meta in log.metadata.items():
        keys = ", ".join(f"{k}={v}" for k, v in meta.items() if k != "config")
        print(f"  metadata {name}: {keys}")
    return 0


def _log_export(args) -> int:
    from cosim.log.export import export_topic

    if args.out:
        check_file(args.out)
    export_topic(args.file, args.topic, args.out, args.format)
    return 0


def _experiment(args) -> int:
    from cosim.experiment.protocol import load_experiment
    from cosim.experiment.runner import run_experiment

    exp, base = load_experiment(args.config, map_path=args.map, participants=args.participants,
                                phase_duration_s=args.phase_duration,
                                participant_driver=args.participant_driver)  # fmt: skip
    if args.participant_driver:
        require_display(f"--participant-driver {args.participant_driver}")
    out = Path(args.out) if args.out else Path("results") / exp.name
    with RunDir(out, force=args.force):
        summary = run_experiment(exp, base, out, jobs=args.jobs, quiet=args.quiet, clip=args.clip)
    if not args.quiet:
        print((out / "summary.md").read_text())
    print(f"results in {out}/ ({summary['wall_s']:.0f} s wall for {summary['simulated_s']:.0f} simulated s)")
    from cosim.experiment.runner import degraded_phases, phases_without_timegap

    for line in degraded_phases(summary):
        print(f"cosim: warning: degraded drive: {line}", file=sys.stderr)
    empty = phases_without_timegap(summary)
    if empty:
        print(f"cosim: error: no time-gap data in {', '.join(empty)}", file=sys.stderr)
        return 1
    return 0


def _compare(args) -> int:
    from cosim.experiment.compare import CompareTolerances, compare_files

    try:
        tol = CompareTolerances(rmse_abs_s=args.rmse_tol) if args.rmse_tol is not None else None
    except ValueError:
        raise CosimError(f"--rmse-tol must be a finite number of seconds >= 0, got {args.rmse_tol}") from None
    result = compare_files(args.a, args.b, tol)
    print(result.table())
    return 0 if result.ok else 1


def _vanet_mac(log) -> str:
    """The run's medium access (``vanet.mac`` of the config in the log's metadata; logs from before issue
    18 have none: SOTDMA, the only MAC then)."""
    try:
        cfg = json.loads(log.metadata.get("cosim", {}).get("config", "{}"))
    except ValueError:
        return "unknown"
    return ((cfg or {}).get("vanet") or {}).get("mac", "sotdma")


def _vanet_report(args) -> int:
    import json

    from cosim.log import read
    from cosim.vanet.report import run_title, vanet_report

    out = check_dir(args.out if args.out else Path(args.file).parent / "vanet")
    log = read(args.file, topics=["/vanet/tx", "/vanet/rx", "/vanet/load", "/vanet/step"])
    if "/vanet/tx" not in log.topics:
        raise CosimError(f"{args.file} has no /vanet/* topics: the run had the radio off (vanet: null)")
    mac = _vanet_mac(log)  # the radio access, in the summary and every plot title (issue 18)
    summary = vanet_report(log.topics, out, title=f"{run_title(log.metadata)}, MAC {mac}")
    print(json.dumps({"mac": mac, **summary}, indent=1, default=str))
    print(f"plots in {out}/")
    return 0


def _radio(args) -> int:
    from cosim.vanet.radio import RadioScenario, plot, plot_many, run_radio, run_radios

    macs = [m.strip() for m in str(args.mac).split(",")]
    if len(set(macs)) != len(macs) or "" in macs:
        raise CosimError(
            f"--mac {args.mac}: give distinct MAC names separated by commas (e.g. sotdma,80211p,cv2x)"
        )
    try:
        scs = [RadioScenario(mac=mac, layout=args.layout, vehicles_per_km=args.vehicles_per_km,
                             stations=args.stations, area_m=args.area_m, lanes=args.lanes, speed_kmh=args.speed_kmh,
                             rate_hz=args.rate_hz, size_bytes=args.size_bytes, tx_dbm=args.tx_dbm,
                             pathloss=args.pathloss, shadowing_db=args.shadowing_db, noise_dbm=args.noise_dbm,
                             cs_dbm=args.cs_dbm, duration_s=args.duration, seed=args.seed) for mac in macs]  # fmt: skip
    except ValueError as exc:
        raise CosimError(str(exc)) from None
    out = check_dir(args.out) if args.out else None
    if len(scs) == 1:
        results = [run_radio(scs[0])]
    else:  # the MACs side by side: same layout, seed, channel and receiver
        results, hists = run_radios(scs)
    payload = results[0] if len(scs) == 1 else results
    if out is not None:
        Path(out).mkdir(parents=True, exist_ok=True)
        (Path(out) / "radio.json").write_text(json.dumps(payload, indent=1) + "\n")
        if len(scs) == 1:
            plot(results[0], scs[0], out)
        else:
            plot_many(results, scs, hists, out)
    if args.json:
        print(json.dumps(payload))
        return 0
    for result in results:
        print(f"{result['mac']}, {result['stations']} stations: cbr {result['cbr']:.3f}, shared slots "
              f"{result['shared_slot_share']}, never sent {result['never_sent_share']:.3f}, "
              f"IPG p95 {result['ipg_p95_s']:.3f} s")  # fmt: skip
        for b in result["pdr"]:
            print(f"  {b['from_m']:6.0f}-{b['to_m']:<6.0f} m  PDR {b['pdr']:.3f}  (n={b['n']})")
    if out is not None:
        print(f"plot and radio.json in {out}/")
    return 0


def build_parser() -> argparse.ArgumentParser:
    from cosim.scenario.demand import DENSITY_NAMES

    p = _Parser(prog="cosim", description="Driving simulator with a lockstep VANET layer (SUMO + MuJoCo).")
    sub = p.add_subparsers(dest="command", required=True)

    b = sub.add_parser("build-scenario", help="build a SUMO scenario from an OSM file")
    b.add_argument("--osm", required=True, help="OSM file (.osm or .osm.gz)")
    b.add_argument("--out", help="directory to write the scenario into (default: only the cache)")
    b.add_argument("--density", choices=DENSITY_NAMES, default="medium")
    b.add_argument("--seed", type=_seed, default=0)
    b.add_argument("--check", type=_seconds, metavar="SECONDS",
                   help="then run SECONDS of its traffic in SUMO and report teleports (added to report.json)")  # fmt: skip
    b.set_defaults(fn=_build_scenario)

    r = sub.add_parser("run", help="run the co-simulation headless from a config")
    r.add_argument("config", nargs="?", help="run config YAML (default: built-in defaults)")
    r.add_argument("--map", help="OSM file to run on instead of the config's map")
    r.add_argument("--density", choices=DENSITY_NAMES)
    r.add_argument("--duration", type=float, help="simulated seconds")
    r.add_argument("--seed", type=_seed)
    r.add_argument("--out", help="output directory (default results/<name>)")
    r.add_argument(
        "--force", action="store_true", help="replace a run already in --out (its outputs are removed)"
    )
    r.add_argument("--gui", action="store_true", help="watch in sumo-gui (TraCI backend)")
    r.add_argument("--quiet", action="store_true", help="no progress bar; print the result as JSON")
    r.set_defaults(fn=_run)

    ex = sub.add_parser("experiment", help="run the A/B/baseline experiment protocol for all participants")
    ex.add_argument("config", help="experiment config YAML (e.g. configs/experiment.yaml)")
    ex.add_argument("--map", help="OSM file to run on instead of the config's map")
    ex.add_argument("--participants", type=int, help="number of participants (profiles repeat)")
    ex.add_argument("--phase-duration", type=float, help="seconds per phase (default: the config's)")
    ex.add_argument("--jobs", type=int, help="parallel processes (default: cores)")
    ex.add_argument("--out", help="output directory (default results/<name>)")
    ex.add_argument("--force", action="store_true",
                    help="replace an experiment already in --out (its outputs are removed)")  # fmt: skip
    ex.add_argument("--quiet", action="store_true")
    ex.add_argument(
        "--participant-driver",
        choices=("keyboard", "wheel"),
        help="a person drives each participant's run in the 3D view (one after the other)",
    )
    ex.add_argument(
        "--clip", action="store_true", help="also render P1's system-A and system-B phases to clip.mp4"
    )
    ex.set_defaults(fn=_experiment)

    cp = sub.add_parser("compare", help="compare two runs' time-gap traces (exit 1 when outside tolerance)")
    cp.add_argument("a", help="reference run: timegap.csv or run.mcap")
    cp.add_argument("b", help="run to check: timegap.csv or run.mcap")
    cp.add_argument("--rmse-tol", type=float, help="RMSE tolerance of the time gap [s] (default 0.02)")
    cp.set_defaults(fn=_compare)

    vr = sub.add_parser("vanet-report", help="V2V metrics of a run: PDR vs distance, channel load, AoI")
    vr.add_argument("file", help="run.mcap")
    vr.add_argument("--out", help="directory for the plots (default: beside the log, vanet/)")
    vr.set_defaults(fn=_vanet_report)

    ra = sub.add_parser(
        "radio", help="synthetic radio calibration scenario: PDR vs distance, CBR, shared slots"
    )
    ra.add_argument("--mac", default="sotdma",
                    help="medium access: sotdma, 80211p or cv2x; several, comma-separated (sotdma,80211p,cv2x), "
                         "run on the same layout and seed and are overlaid in one plot")  # fmt: skip
    ra.add_argument("--layout", choices=("highway", "square"), required=True)
    dens = ra.add_mutually_exclusive_group(required=True)
    dens.add_argument("--vehicles-per-km", type=float, help="highway density, all lanes together")
    dens.add_argument("--stations", type=int, help="number of stations")
    ra.add_argument("--area-m", type=float, help="square side / road length [m] (default 300 / 5000)")
    ra.add_argument("--lanes", type=int, default=3, help="lanes per direction (highway, default 3)")
    ra.add_argument("--speed-kmh", type=float, default=0.0, help="highway speed (default 0: standing)")
    ra.add_argument("--rate-hz", type=float, required=True, help="CAMs per second per station")
    ra.add_argument("--size-bytes", type=int, required=True, help="CAM size (the MAC adds its headers)")
    ra.add_argument("--tx-dbm", type=float, required=True, help="transmit power [dBm]")
    ra.add_argument("--pathloss", required=True,
                    help="free-space, two-ray, log-distance, winner-b1, 3gpp-highway or 3gpp-urban")  # fmt: skip
    ra.add_argument("--shadowing-db", type=float, help="log-normal shadowing sigma (default: the model's)")
    ra.add_argument(
        "--noise-dbm", type=float, help="noise floor (default: -174 dBm/Hz + 10 log10(10 MHz) + 9 dB)"
    )
    ra.add_argument("--cs-dbm", type=float, default=-85.0, help="carrier-sense threshold (default -85 dBm)")
    ra.add_argument("--duration", type=_seconds, default=30.0, help="simulated seconds (first 10 s: warm-up)")
    ra.add_argument("--seed", type=_seed, default=1)
    ra.add_argument("--json", action="store_true", help="print the result as one JSON object")
    ra.add_argument("--out", help="directory for pdr_vs_distance.png and radio.json")
    ra.set_defaults(fn=_radio)

    from cosim.sweep.cli import add_sweep_parser
    from cosim.world3d.cli import add_drive_parser, add_render_parser

    add_sweep_parser(sub)
    add_drive_parser(sub)
    add_render_parser(sub)

    lg = sub.add_parser("log", help="inspect a run's MCAP log")
    lsub = lg.add_subparsers(dest="log_command", required=True)
    li = lsub.add_parser("info", help="topics, counts and duration")
    li.add_argument("file")
    li.set_defaults(fn=_log_info)
    le = lsub.add_parser("export", help="export one topic as CSV or JSON lines")
    le.add_argument("file")
    le.add_argument("--topic", required=True)
    le.add_argument("--format", choices=["csv", "json"], default="csv",
                    help="csv: one row per item; json: JSON lines, one message per line (nested topics)")  # fmt: skip
    le.add_argument("--csv", dest="format", action="store_const", const="csv", help=argparse.SUPPRESS)
    le.add_argument("--out", help="output file (default: stdout)")
    le.set_defaults(fn=_log_export)
    return p


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    # a run started from a script in the background inherits SIGINT ignored; it must still stop cleanly
    # (with a complete log) when someone sends it SIGINT
    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.signal(signal.SIGTERM, _terminated)
    try:
        return args.fn(args)
    except CosimError as exc:
        print(f"cosim: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("cosim: interrupted", file=sys.stderr)
        return _signal_exit
    except BrokenPipeError:  # output piped into `head` (before OSError, which it is a kind of)
        # stdout is gone: point it at /dev/null so the interpreter's final flush does not fail again
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except OSError as exc:  # a write the checks above could not foresee (disk full, permission changed ...)
        if exc.filename is None or exc.errno not in _USER_ERRNOS:
            raise
        print(f"cosim: error: cannot write {exc.filename}: {exc.strerror}", file=sys.stderr)
        return 2


_USER_ERRNOS = {errno.EACCES, errno.EPERM, errno.EROFS, errno.ENOTDIR, errno.EISDIR, errno.EEXIST, errno.ENOSPC,
                errno.EDQUOT}  # fmt: skip

if __name__ == "__main__":
    sys.exit(main())
