"""The experiment's time-gap plot says which phase has no data instead of leaving its panel blank."""

import numpy as np

from cosim.experiment import analysis


def _cols(gap_b: float) -> dict[str, np.ndarray]:
    n = 20
    t = np.arange(n, dtype=float)
    phase = np.array(["baseline"] * 10 + ["system_B"] * 10)
    gap = np.where(phase == "baseline", 2.0, gap_b)
    return {
        "t_s": t,
        "time_gap_true_s": gap,
        "time_gap_displayed_s": np.full(n, np.nan),
        "warning": np.array(["none"] * n),
        "phase": phase,
        "system": np.where(phase == "baseline", "none", "B"),
    }


def _texts(monkeypatch, tmp_path, cols) -> list[str]:
    import matplotlib.pyplot as plt

    seen: list[str] = []
    close = plt.close

    def keep(fig):
        seen.extend(t.get_text() for ax in fig.axes for t in ax.texts)
        close(fig)

    monkeypatch.setattr(plt, "close", keep)
    analysis.plot_timegap(cols, tmp_path / "tg.png", "P1")
    assert (tmp_path / "tg.png").stat().st_size > 0
    return seen


def test_a_phase_without_time_gaps_is_labelled(monkeypatch, tmp_path):
    texts = _texts(monkeypatch, tmp_path, _cols(np.inf))
    assert texts.count("no time-gap data in this phase") == 1


def test_phases_with_time_gaps_carry_no_label(monkeypatch, tmp_path):
    assert "no time-gap data in this phase" not in _texts(monkeypatch, tmp_path, _cols(3.0))
