"""Same inputs -> identical trajectory, for two instances and for reset-and-replay on one instance."""

from __future__ import annotations

import numpy as np

from cosim.ego_mujoco import EgoCar


def controls(seed: int, n: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    u = np.empty((n, 3))
    u[:, 0] = rng.uniform(0.0, 1.0, n) * (rng.uniform(size=n) < 0.7)  # throttle
    u[:, 1] = rng.uniform(0.0, 1.0, n) * (rng.uniform(size=n) < 0.2)  # brake
    u[:, 2] = np.clip(np.cumsum(rng.normal(0.0, 0.1, n)), -1.0, 1.0)  # steering wanders
    return u


def trajectory(car: EgoCar, u: np.ndarray) -> np.ndarray:
    car.reset(3.0, -4.0, 0.4, 8.0)
    rows = []
    for throttle, brake, steer in u:
        car.step(float(throttle), float(brake), float(steer), 0.1)
        rows.append(np.concatenate([car.data.qpos, car.data.qvel, car.data.act]))
    return np.array(rows)


def test_identical_trajectories() -> None:
    u = controls(42, 200)  # 20 s of driving with hard braking, throttle and steering
    a, b = EgoCar(), EgoCar()
    first = trajectory(a, u)
    np.testing.assert_array_equal(trajectory(b, u), first)  # a second instance
    np.testing.assert_array_equal(trajectory(a, u), first)  # the same instance after reset
    assert not np.array_equal(trajectory(b, controls(43, 200)), first)  # other inputs differ
