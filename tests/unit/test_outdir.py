"""cosim.outdir: the checks of --out, the lock, --force, and no half-written folder after a user error."""

from __future__ import annotations

import math

import pytest

from cosim.config import SEED_MAX, from_dict
from cosim.errors import ConfigError, CosimError
from cosim.outdir import LOCK_NAME, RunDir, check_dir, check_file
from cosim.runconfig import RunConfig


def test_check_dir_and_check_file_name_the_problem(tmp_path):
    a_file = tmp_path / "f"
    a_file.write_text("x")
    with pytest.raises(CosimError, match="is a file, not a directory"):
        check_dir(a_file)
    with pytest.raises(CosimError, match="lies under .* which is a file"):
        check_dir(a_file / "a" / "b")
    with pytest.raises(CosimError, match="is a directory: give a file name"):
        check_file(tmp_path)
    with pytest.raises(CosimError, match="which is a file"):
        check_file(a_file / "x.csv", "--frames")
    assert check_dir(tmp_path / "new" / "deeper") == tmp_path / "new" / "deeper"
    assert not (tmp_path / "new").exists()  # a check creates nothing


def test_run_dir_is_locked_while_written(tmp_path):
    out = tmp_path / "run"
    with RunDir(out):
        assert (out / LOCK_NAME).exists()
        with pytest.raises(CosimError, match="being written by another cosim run"), RunDir(out):
            pass
        (out / "run.mcap").write_bytes(b"first")
    assert not (out / LOCK_NAME).exists()
    assert (out / "run.mcap").read_bytes() == b"first"  # the refused second one touched nothing


def test_an_existing_run_is_replaced_only_with_force(tmp_path):
    out = tmp_path / "run"
    out.mkdir()
    (out / "run.mcap").write_bytes(b"old")
    (out / "vanet").mkdir()
    (out / "vanet" / "pdr.png").write_bytes(b"old plot")
    with pytest.raises(CosimError, match="already holds a run: add --force"), RunDir(out):
        pass
    assert (out / "vanet" / "pdr.png").exists()
    with RunDir(out, force=True):
        assert sorted(p.name for p in out.iterdir()) == [LOCK_NAME]  # nothing stale beside the new run
    # an experiment folder (a participant's run one level down) counts as a run too
    (out / "P1").mkdir()
    (out / "P1" / "run.mcap").write_bytes(b"old")
    with pytest.raises(CosimError, match="already holds a run"), RunDir(out):
        pass
    with RunDir(out, keep_existing=True):  # a sweep resumes in its folder
        assert (out / "P1" / "run.mcap").exists()


def test_a_folder_created_for_a_run_that_fails_with_a_user_error_is_removed(tmp_path):
    out = tmp_path / "new"
    with pytest.raises(CosimError), RunDir(out):
        (out / "run.mcap").write_bytes(b"half")
        raise CosimError("bad map")
    assert not out.exists()
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    with pytest.raises(CosimError), RunDir(out):  # a folder that was there stays
        raise CosimError("bad map")
    assert (out / "notes.txt").read_text() == "mine"


@pytest.mark.parametrize(
    ("data", "words"),
    [
        ({"duration_s": math.nan}, "config duration_s: expected a finite number, got nan"),
        ({"duration_s": math.inf}, "config duration_s: expected a finite number, got inf"),
        ({"duration_s": 0.04}, "shorter than one step"),
        ({"seed": -1}, "config seed: must be an integer from 0 to"),
        ({"seed": SEED_MAX + 1}, "config seed: must be an integer from 0 to"),
        ({"ego": {"driver_seed": -2}}, "config ego.driver_seed: must be"),
        ({"vanet": {"obu": {"table_frames": 5}}}, "replaced by obu.map_memory_s"),
        ({"vanet": {"obu": {"map_memory_s": 0}}}, "map_memory_s must be in (0, 60]"),
        # system B's no-data timeout must fit the OBU map's memory
        (
            {"vanet": {"obu": {"map_memory_s": 2.5, "stale_after_s": 2.0}}},
            "must not exceed vanet.obu.map_memory_s",
        ),
        ({"adas": {"v2v": {"max_data_age_s": 6.0}}}, "must not exceed vanet.obu.map_memory_s (5.0 s)"),
    ],
)
def test_run_config_refuses_values_no_run_can_have(data, words):
    with pytest.raises(ConfigError) as err:
        from_dict(RunConfig, data)
    assert words in str(err.value)


def test_system_b_timeout_up_to_the_map_memory_is_accepted():
    cfg = from_dict(
        RunConfig, {"vanet": {"obu": {"map_memory_s": 6.0}}, "adas": {"v2v": {"max_data_age_s": 6.0}}}
    )
    assert cfg.vanet.obu.map_memory_s == cfg.adas.v2v.max_data_age_s == 6.0
    assert from_dict(RunConfig, {"vanet": None, "adas": {"v2v": {"max_data_age_s": 9.0}}}).vanet is None


def test_the_largest_seed_is_accepted():
    assert from_dict(RunConfig, {"seed": SEED_MAX}).seed == SEED_MAX
