import dataclasses

import numpy as np
import pytest

from cosim.config import from_dict
from cosim.driver import DriverConfig, ScriptedDriver, make_driver
from cosim.driver.profiles import PROFILES, DriverProfile, profile_by_name
from cosim.errors import ConfigError


def test_presets_exist_and_are_valid():
    assert {"daily_commuter", "occasional_driver", "cautious", "aggressive"} <= set(PROFILES)
    for prof in PROFILES.values():
        dataclasses.replace(prof)  # re-runs __post_init__
    c, o = profile_by_name("daily_commuter"), profile_by_name("occasional_driver")
    # the occasional driver reacts later, keeps more distance, drives slower
    assert o.reaction_time_s > c.reaction_time_s
    assert o.desired_time_gap_s > c.desired_time_gap_s
    assert o.desired_speed_factor < c.desired_speed_factor
    for prof in PROFILES.values():
        assert 0.8 <= prof.reaction_time_s <= 1.5
        assert 0.9 <= prof.desired_time_gap_s <= 1.8


def test_profile_by_name_lists_known_names():
    with pytest.raises(ValueError) as exc:
        profile_by_name("sunday_driver")
    for name in PROFILES:
        assert name in str(exc.value)


@pytest.mark.parametrize(
    "field,value",
    [("reaction_time_s", 0.0), ("reaction_time_s", 9.0), ("desired_time_gap_s", -1.0), ("a_brake_prob", 1.5),
     ("b_compliance", -0.1), ("lateral_wander_std_m", -0.1), ("min_gap_m", float("nan")), ("a_gap_max_s", 0.1)],
)  # fmt: skip
def test_profile_rejects_impossible_values(field, value):
    with pytest.raises(ValueError, match=field):
        dataclasses.replace(DriverProfile(), **{field: value})


def test_without_noise_switches_off_only_randomness():
    p = profile_by_name("occasional_driver")
    q = p.without_noise()
    assert q.gap_error_rel == q.inv_ttc_error_ps == q.speed_wander_frac == q.lateral_wander_std_m == 0.0
    assert q.reaction_time_s == p.reaction_time_s and q.desired_time_gap_s == p.desired_time_gap_s


def test_driver_config_from_yaml_mapping():
    cfg = from_dict(
        DriverConfig,
        {"kind": "scripted", "profile": "occasional_driver", "profile_overrides": {"reaction_time_s": 1.4}},
    )
    assert cfg.resolved_profile().reaction_time_s == 1.4
    drv = make_driver(cfg, np.random.default_rng(0), 0.6, 2.7)
    assert isinstance(drv, ScriptedDriver) and drv.profile.reaction_time_s == 1.4
    with pytest.raises(ConfigError, match="known profiles"):
        from_dict(DriverConfig, {"profile": "nobody"})
    with pytest.raises(ConfigError, match="unknown parameter 'reaction'"):
        from_dict(DriverConfig, {"profile_overrides": {"reaction": 1.0}})
    with pytest.raises(ConfigError, match="reaction_time_s"):
        from_dict(DriverConfig, {"profile_overrides": {"reaction_time_s": -1.0}})
    with pytest.raises(ConfigError, match="kind"):
        from_dict(DriverConfig, {"kind": "joystick"})
