"""Bad input to the scenario builder: one clear line, exit code 2, nothing half-written left behind."""

from __future__ import annotations

import gzip
import os
import subprocess
import sys
from pathlib import Path

import pytest
from osm_factory import OsmSketch
from testpaths import shared_map


def cosim(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "cosim.cli", *args], capture_output=True, text=True, cwd=cwd,
                          env=os.environ.copy())  # fmt: skip


def assert_clean_failure(proc, words: str, out_dir):
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert words in lines[0], lines[0]
    assert not out_dir.exists()
    cache = os.environ["COSIM_CACHE_DIR"]
    leftovers = (
        [p for p in os.listdir(cache) if p.startswith(("net-", "scn-"))] if os.path.isdir(cache) else []
    )
    assert not leftovers


def test_missing_file(tmp_path):
    assert_clean_failure(cosim("build-scenario", "--osm", str(tmp_path / "nope.osm"), "--out", str(tmp_path / "o")),
                         "does not exist", tmp_path / "o")  # fmt: skip


def test_truncated_gzip(tmp_path):
    data = shared_map("munich").read_bytes()
    bad = tmp_path / "cut.osm.gz"
    bad.write_bytes(data[: len(data) // 2])
    assert_clean_failure(
        cosim("build-scenario", "--osm", str(bad), "--out", str(tmp_path / "o")), "cut.osm.gz", tmp_path / "o"
    )


def test_xml_that_is_not_osm(tmp_path):
    bad = tmp_path / "x.osm"
    bad.write_text("<?xml version='1.0'?><html><body/></html>")
    assert_clean_failure(cosim("build-scenario", "--osm", str(bad), "--out", str(tmp_path / "o")),
                         "not an OpenStreetMap", tmp_path / "o")  # fmt: skip


def test_garbage_bytes(tmp_path):
    bad = tmp_path / "g.osm.gz"
    with gzip.open(bad, "wb") as fh:
        fh.write(b"\x00\x01 this is not xml")
    assert_clean_failure(
        cosim("build-scenario", "--osm", str(bad), "--out", str(tmp_path / "o")), "g.osm.gz", tmp_path / "o"
    )


def test_pbf_is_named_with_the_way_to_convert_it(tmp_path):
    """Extracts often come as .osm.pbf, which netconvert cannot read: say so, not "corrupt XML"."""
    bad = tmp_path / "town.osm.pbf"
    # a PBF file opens with a 4-byte length and the BlobHeader of its "OSMHeader" blob
    bad.write_bytes(b"\x00\x00\x00\x0e\x0a\x09OSMHeader\x18\x7b\x10\x73" + bytes(64))
    assert_clean_failure(cosim("build-scenario", "--osm", str(bad), "--out", str(tmp_path / "o")),
                         "is OSM PBF", tmp_path / "o")  # fmt: skip


def test_osm_without_drivable_roads(tmp_path):
    s = OsmSketch()
    s.node("a", 0, 0)
    s.node("b", 100, 0)
    s.way(["a", "b"], highway="footway")
    osm = s.write(tmp_path / "paths.osm")
    assert_clean_failure(
        cosim("build-scenario", "--osm", str(osm), "--out", str(tmp_path / "o")),
        "no drivable road",
        tmp_path / "o",
    )


def test_unknown_density(tmp_path):
    proc = cosim("build-scenario", "--osm", str(shared_map("munich")), "--density", "extreme")
    assert proc.returncode == 2 and "invalid choice" in proc.stderr


@pytest.mark.parametrize(
    ("yaml_text", "words"),
    [
        ("seed: 1\nfoo: 2\n", "config foo: unknown key"),
        ("ego:\n  depart_s: abc\n", "config ego.depart_s: expected a number"),
        (
            "timing:\n  physics_timestep_s: 0.003\n",
            "config timing: sumo_step_s (0.1) must be an integer multiple",
        ),
        ("timing:\n  sumo_step_s: 0.2\n", "config timing: sumo_step_s must be <= 0.1 s"),
        ("timing:\n  cam_check_period_s: 0.1\n", "config timing.cam_check_period_s: unknown key"),
        ("scenario:\n  demand:\n    density: extreme\n", "unknown density 'extreme'"),
        ("seed: [1\n", "is not valid YAML"),
    ],
)
def test_config_errors_name_the_key(tmp_path, yaml_text, words):
    cfg = tmp_path / "c.yaml"
    cfg.write_text(yaml_text)
    proc = cosim("run", str(cfg), "--out", str(tmp_path / "o"))
    assert proc.returncode == 2, proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1 and words in proc.stderr, proc.stderr


# -- every command: one line naming the problem and the fix, exit 2, nothing written ---------------------


@pytest.fixture(scope="module")
def small_map(tmp_path_factory):
    from osm_factory import crossroads

    return crossroads().write(tmp_path_factory.mktemp("map") / "x.osm")


def cosim_here(*args, env: dict[str, str | None] | None = None) -> subprocess.CompletedProcess:
    """``cosim ARGS`` in this process (a check that refuses input needs no simulator: ~100x faster than a child
    process); ``env``: variables to set (None: unset) meanwhile. Any exception other than the exit is a failure."""
    import contextlib
    import io
    import signal

    from cosim.cli import main

    saved_env = {k: os.environ.get(k) for k in env or {}}
    handlers = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    err, out = io.StringIO(), io.StringIO()
    try:
        for k, v in (env or {}).items():
            os.environ.pop(k, None) if v is None else os.environ.__setitem__(k, v)
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
            try:
                rc = main([str(a) for a in args])
            except SystemExit as exc:  # argparse
                rc = exc.code
    finally:
        for k, v in saved_env.items():
            os.environ.pop(k, None) if v is None else os.environ.__setitem__(k, v)
        for sig, handler in handlers.items():
            signal.signal(sig, handler)
    return subprocess.CompletedProcess(args, rc, out.getvalue(), err.getvalue())


def one_line(proc, words: str) -> str:
    assert proc.returncode == 2, proc.stderr[-3000:]
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr[-3000:]
    assert words in lines[0], lines[0]
    return lines[0]


def unwritable_dir(tmp_path):
    """A directory this process may not create entries in (root ignores permission bits: /proc/1 then)."""
    if os.geteuid() == 0:
        if os.access("/proc/1", os.W_OK):
            pytest.skip("no unwritable directory for root here")
        return Path("/proc/1")
    d = tmp_path / "ro"
    d.mkdir()
    d.chmod(0o500)
    return d


@pytest.fixture
def damaged_log(tmp_path):
    """A complete MCAP log (with the topics every reader looks for) whose third of six chunks is damaged."""
    from mcap.reader import make_reader

    from cosim.log import McapLog

    path = tmp_path / "damaged.mcap"
    with McapLog(path, chunk_size=2048, flush_every_s=1.0, background=False) as log:
        log.metadata("cosim", {"seed": 1, "config": "{}"})
        for i in range(60):
            t = i * 0.1
            log.write("/ego/state", t, {"t_s": t, "x_m": float(i), "note": "x" * 40})
            log.write("/adas/state", t, {"t_s": t, "b_timegap_s": 2.5})
            log.write("/vanet/tx", t, {"t_s": t, "station": [1, 2], "bytes": [200, 300]})
    with path.open("rb") as fh:
        chunks = make_reader(fh).get_summary().chunk_indexes
    assert len(chunks) >= 5
    data = bytearray(path.read_bytes())
    mid = chunks[2]
    start = mid.chunk_start_offset + mid.chunk_length // 2
    for i in range(start, start + 16):
        data[i] ^= 0x5A
    path.write_bytes(bytes(data))
    return path


def test_damaged_chunk_is_one_line_for_every_reader(tmp_path, damaged_log):
    cases = {
        "log info": ("log", "info", damaged_log),
        "log export": ("log", "export", damaged_log, "--topic", "/ego/state", "--out", tmp_path / "e.csv"),
        "render": ("render", damaged_log, "--frames", tmp_path / "frames", "--size", "64x64"),
        "compare": ("compare", damaged_log, damaged_log),
        "vanet-report": ("vanet-report", damaged_log, "--out", tmp_path / "vr"),
    }
    for name, args in cases.items():
        line = one_line(cosim(*map(str, args)), "is damaged")
        assert "re-run" in line and "damaged.mcap" in line, (name, line)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["damaged.mcap"]  # no CSV, frames or plots


def test_out_that_cannot_be_a_directory(tmp_path, small_map, damaged_log):
    a_file = tmp_path / "a_file"
    a_file.write_text("x")
    ro = unwritable_dir(tmp_path)
    cfg = ("--map", str(small_map), "--duration", "2", "--quiet")
    for out, words in ((a_file, "is a file, not a directory"), (a_file / "sub", "which is a file"),
                       (ro / "sub", "no permission to write")):  # fmt: skip
        one_line(cosim_here("run", *cfg, "--out", str(out)), words)
        one_line(cosim_here("build-scenario", "--osm", str(small_map), "--out", str(out)), words)
        one_line(cosim_here("vanet-report", str(damaged_log), "--out", str(out)), words)
        one_line(cosim_here("render", str(damaged_log), "--frames", str(out)), words)
        sweep = tmp_path / "s.yaml"
        sweep.write_text(f"name: s\noverrides: {{scenario.map: {small_map}, duration_s: 2}}\nseeds: [1]\n")
        one_line(cosim_here("sweep", str(sweep), "--out", str(out)), words)
    one_line(cosim_here("render", str(damaged_log), "--out", str(a_file / "v.mp4")), "which is a file")
    one_line(cosim_here("log", "export", str(damaged_log), "--topic", "/ego/state", "--out", str(tmp_path)),
             "is a directory")  # fmt: skip
    one_line(cosim_here("log", "export", str(damaged_log), "--topic", "/ego/state", "--out", str(ro / "e.csv")),
             "no permission")  # fmt: skip
    assert a_file.read_text() == "x"


def _scenarios():
    root = Path(os.environ["COSIM_CACHE_DIR"]) / "scenarios"
    return sorted(os.listdir(root)) if root.is_dir() else []


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (("--duration", "nan"), "config duration_s: expected a finite number, got nan"),
        (("--duration", "inf"), "config duration_s: expected a finite number, got inf"),
        (("--duration", "0.05"), "shorter than one step"),
        (("--seed", "-1"), "--seed: must be an integer from 0 to 2147483647"),
        (("--seed", str(2**31)), "--seed: must be an integer from 0 to 2147483647"),
        (("--gui",), "--gui (sumo-gui) needs a display"),
    ],
)
def test_run_refuses_before_building_anything(tmp_path, small_map, args, words):
    before = _scenarios()
    proc = cosim_here("run", "--map", small_map, "--seed", "7", "--duration", "3", *args, "--out", tmp_path / "o",
                      env={"DISPLAY": None, "WAYLAND_DISPLAY": None})  # fmt: skip
    one_line(proc, words)
    assert not (tmp_path / "o").exists()
    assert _scenarios() == before  # no scenario built (a too-large seed used to leave a broken one)


def test_gui_with_a_dead_display_is_refused_at_once(tmp_path, small_map):
    """A DISPLAY left over from a closed session: one line naming it, not a minute of TraCI retries."""
    proc = cosim_here("run", "--map", small_map, "--duration", "3", "--gui", "--out", tmp_path / "o",
                      env={"DISPLAY": ":987", "WAYLAND_DISPLAY": None})  # fmt: skip
    one_line(proc, "--gui (sumo-gui) needs a display, but no display server answers at DISPLAY=:987")
    assert not (tmp_path / "o").exists()


def test_seed_in_a_config_file_is_checked_too(tmp_path, small_map):
    cfg = tmp_path / "c.yaml"
    cfg.write_text(f"seed: {2**40}\nscenario: {{map: {small_map}}}\n")
    one_line(
        cosim_here("run", str(cfg), "--out", str(tmp_path / "o")), "config seed: must be an integer from 0"
    )
    cfg.write_text(f"scenario: {{map: {small_map}}}\nego: {{driver_seed: -3}}\n")
    one_line(cosim_here("run", str(cfg), "--out", str(tmp_path / "o")), "config ego.driver_seed: must be")
    assert not (tmp_path / "o").exists()


def test_build_scenario_check_must_be_positive(tmp_path, small_map):
    before = _scenarios()
    one_line(cosim_here("build-scenario", "--osm", str(small_map), "--check", "-5", "--out", str(tmp_path / "o")),
             "argument --check: must be a finite number of seconds > 0, got -5")  # fmt: skip
    assert not (tmp_path / "o").exists() and _scenarios() == before


def test_compare_rmse_tol_must_be_non_negative(damaged_log):
    one_line(cosim_here("compare", str(damaged_log), str(damaged_log), "--rmse-tol", "-1"),
             "--rmse-tol must be a finite number of seconds >= 0, got -1.0")  # fmt: skip


@pytest.mark.parametrize("how", ["drive", "experiment"])
def test_a_person_driving_needs_a_display(tmp_path, small_map, how):
    if how == "drive":
        args = ["drive", "--map", small_map, "--driver", "keyboard", "--duration", "3"]
        words = "cosim drive --driver keyboard needs a display"
    else:
        args = ["experiment", Path(__file__).parents[2] / "configs" / "experiment.yaml", "--participant-driver",
                "keyboard"]  # fmt: skip
        words = "--participant-driver keyboard needs a display"
    no_display = {"DISPLAY": None, "WAYLAND_DISPLAY": None, "SDL_VIDEODRIVER": None}
    one_line(cosim_here(*args, "--out", tmp_path / "o", env=no_display), words)
    assert not (tmp_path / "o").exists()


def test_run_with_a_person_driving_points_to_cosim_drive(tmp_path, small_map):
    cfg = tmp_path / "c.yaml"
    cfg.write_text(f"scenario: {{map: {small_map}}}\nego: {{driver: {{kind: keyboard}}}}\n")
    one_line(cosim_here("run", str(cfg), "--duration", "3", "--out", str(tmp_path / "o")),
             "ego.driver.kind: keyboard is a person driving: use `cosim drive`")  # fmt: skip
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("command", ["run", "drive", "experiment"])
def test_a_folder_holding_a_run_is_replaced_only_with_force(tmp_path, small_map, command):
    out = tmp_path / "o"
    (out / "P1").mkdir(parents=True)
    (out / "P1" / "run.mcap").write_bytes(b"an earlier run")
    args = {
        "run": ["run", "--map", small_map],
        "drive": ["drive", "--map", small_map, "--driver", "scripted"],
        "experiment": [
            "experiment",
            Path(__file__).parents[2] / "configs" / "experiment.yaml",
            "--map",
            small_map,
        ],
    }[command]
    one_line(cosim_here(*args, "--out", out), f"--out {out} already holds a run: add --force to replace it")
    assert (out / "P1" / "run.mcap").read_bytes() == b"an earlier run"
