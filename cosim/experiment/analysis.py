"""From a participant's log to the paper's Fig. 4 and the summary numbers."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from cosim.health import involves_ego
from cosim.log import Log
from cosim.vanet.channel import OUTCOME_NAMES

HARD_BRAKE_MPS2 = -4.0  # deceleration counted as hard braking (a common naturalistic-driving threshold)
NO_LEADER_GAP_S = 9.99  # system B caps the time gap at 10 s; at the cap nobody is being followed


def timegap_columns(log: Log, start_s: float) -> dict[str, np.ndarray]:
    """timegap.csv's columns from /adas/state, time relative to the protocol start; with a lead car also
    ``lead_paced`` (1: the ego set the lead's pace at that step, /ego/state), so that an analysis can leave
    out the samples whose gap the lead shaped."""
    a = log.topics["/adas/state"]
    keep = a["t_s"] >= start_s - 1e-9
    cols = {
        "t_s": np.round(a["t_s"][keep] - start_s, 3),
        "phase": a["phase"][keep],
        "system": a["system"][keep],
        "time_gap_true_s": a["time_gap_true_s"][keep].astype(float),
        "time_gap_displayed_s": np.asarray(a["time_gap_displayed_s"][keep], dtype=float),
        "warning": a["warning"][keep],
    }
    e = log.topics.get("/ego/state", {})
    if "lead_paced" in e:  # both topics have one message per step at the same time
        paced = dict(zip(np.round(e["t_s"], 3).tolist(), e["lead_paced"].tolist(), strict=True))
        cols["lead_paced"] = np.array(
            [int(bool(paced.get(t))) for t in np.round(a["t_s"][keep], 3).tolist()], dtype=int
        )
    return cols


def write_timegap_csv(cols: dict[str, np.ndarray], path: Path) -> None:
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        names = list(cols)
        w.writerow(names)
        for row in zip(*(cols[n] for n in names), strict=True):
            w.writerow(["" if isinstance(v, float) and math.isnan(v) else v for v in row])


def _onsets(flags: np.ndarray) -> int:
    f = np.asarray(flags, dtype=bool)
    return int(np.count_nonzero(f[1:] & ~f[:-1]) + (1 if f.size and f[0] else 0))


def phase_summary(log: Log, cols: dict[str, np.ndarray], start_s: float) -> list[dict]:
    """Per phase: time-gap statistics, warnings, hard braking, minimum TTC, V2V delivery to the leader."""
    a = log.topics["/adas/state"]
    e = log.topics["/ego/state"]
    rx = log.topics.get("/vanet/rx")
    ev = log.topics.get("/events", {})
    ego_collision_t = (  # the ego as collider or as victim, the rule the drive health counts by
        ev["t_s"][[k == "collision" and involves_ego(v, d) for k, v, d in zip(ev["kind"], ev["vehicle"],
                                                                          ev["detail"], strict=True)]]
        if "kind" in ev
        else np.zeros(0)
    )  # fmt: skip
    out = []
    for phase in dict.fromkeys(cols["phase"]):
        m = cols["phase"] == phase
        t0, t1 = cols["t_s"][m][0] + start_s, cols["t_s"][m][-1] + start_s
        tg = cols["time_gap_true_s"][m]
        measured = np.isfinite(tg) & (tg < NO_LEADER_GAP_S)  # a leader close enough for a time gap
        free = measured & (cols["lead_paced"][m] == 0) if "lead_paced" in cols else None
        warn = cols["warning"][m]
        am = (a["t_s"] >= t0) & (a["t_s"] <= t1)
        gap, ls = a["gap_true_m"][am].astype(float), a["leader_speed_mps"][am].astype(float)
        em = (e["t_s"] >= t0) & (e["t_s"] <= t1)
        speed = e["physics_speed_mps"][em].astype(float) if "physics_speed_mps" in e else e["speed_mps"][em]
        es = np.interp(a["t_s"][am], e["t_s"][em], speed) if em.any() else np.zeros(am.sum())
        closing = es - ls
        ok = (closing > 0.1) & np.isfinite(gap) & (gap > 0.0)  # overlaps are collisions, counted below
        ttc = np.where(ok, gap / np.where(ok, closing, 1.0), np.inf)
        accel = np.gradient(speed, e["t_s"][em]) if em.sum() > 2 else np.zeros(0)
        pdr = math.nan
        if rx is not None and "b_station" in a:
            rm = (rx["t_s"] >= t0) & (rx["t_s"] <= t1)
            st = np.interp(rx["t_s"][rm], a["t_s"][am], a["b_station"][am].astype(float)) if am.any() else []
            hit = rx["sender_station_id"][rm] == np.round(st)
            if np.any(hit):
                pdr = float(np.mean(rx["outcome"][rm][hit] == OUTCOME_NAMES.index("ok")))
        out.append({
            "phase": str(phase), "system": str(cols["system"][m][0]),
            "duration_s": round(float(cols["t_s"][m][-1] - cols["t_s"][m][0]), 1),
            "time_gap_mean_s": _r(np.mean(tg[measured])) if measured.any() else None,
            # the same without the samples in which the ego set the lead's pace
            "time_gap_mean_lead_free_s": _r(np.mean(tg[free])) if free is not None and free.any() else None,
            "time_gap_sd_s": _r(np.std(tg[measured])) if measured.any() else None,
            "share_below_2s": _r(np.mean(tg[measured] < 2.0)) if measured.any() else None,
            "share_below_1s": _r(np.mean(tg[measured] < 1.0)) if measured.any() else None,
            "warnings": _onsets(warn == "warning"), "advisories": _onsets(warn == "advisory"),
            "hard_braking_events": _onsets(accel < HARD_BRAKE_MPS2),
            "ego_collisions": _onsets(np.isin(np.round(a["t_s"][am], 3), np.round(ego_collision_t, 3))),
            "min_ttc_s": _r(np.min(ttc)) if np.isfinite(ttc).any() else None,
            "v2v_pdr_to_leader": _r(pdr) if math.isfinite(pdr) else None,
        })  # fmt: skip
    return out


def _r(v, nd: int = 3):
    return None if v is None or not math.isfinite(float(v)) else round(float(v), nd)


def plot_timegap(cols: dict[str, np.ndarray], path: Path, title: str) -> None:
    """The paper's Fig. 4 view: time gap over time per phase, warnings marked."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = cols["t_s"]
    fig, ax = plt.subplots(figsize=(11, 3.8), dpi=110)
    tg = np.where(cols["time_gap_true_s"] < NO_LEADER_GAP_S, cols["time_gap_true_s"], np.nan)
    ax.plot(t, tg, color="0.15", lw=1.0, label="time gap (ground truth)")
    shown = cols["time_gap_displayed_s"]
    if np.isfinite(shown).any():
        ax.plot(t, np.where(shown < NO_LEADER_GAP_S, shown, np.nan), color="tab:blue", lw=0.8, alpha=0.8,
                label="time gap shown by system B")  # fmt: skip
    if "lead_paced" in cols and cols["lead_paced"].any():  # where the gap is partly the lead's doing
        ax.fill_between(t, 0, 0.04, where=cols["lead_paced"] == 1, color="tab:purple", alpha=0.6,
                        transform=ax.get_xaxis_transform(), label="lead paced by the ego")  # fmt: skip
    for level, color in (("advisory", "gold"), ("warning", "tab:red")):
        on = cols["warning"] == level
        if on.any():
            ax.fill_between(t, 0, 1, where=on, color=color, alpha=0.25, transform=ax.get_xaxis_transform(),
                            label=f"{level} shown" if level == "advisory" else "warning shown")  # fmt: skip
    for phase in dict.fromkeys(cols["phase"]):
        m = cols["phase"] == phase
        t0 = t[m][0]
        ax.axvline(t0, color="0.5", lw=0.8, ls="--")
        ax.text(
            t0 + 3,
            0.97,
            f"{phase} ({cols['system'][m][0]})",
            transform=ax.get_xaxis_transform(),
            va="top",
            fontsize=9,
        )
        if not np.isfinite(tg[m]).any():  # an empty panel reads as "no close leader": say why it is empty
            ax.text((t0 + t[m][-1]) / 2, 0.5, "no time-gap data in this phase", transform=ax.get_xaxis_transform(),
                    ha="center", va="center", fontsize=10, color="tab:red")  # fmt: skip
    for y in (1.0, 2.0, 3.0):
        ax.axhline(y, color="0.8", lw=0.6, zorder=0)
    ax.set_xlim(t[0], t[-1])
    ax.set_ylim(0, 6)
    ax.set_xlabel("time since start of the drive [s]")
    ax.set_ylabel("time gap to the leader [s]")
    ax.set_title(title)
    # below the axes: inside, it hid the label of the last phase
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.2), fontsize=8, ncols=4, frameon=False)
    fig.tight_layout()
    fig.savefig(path, bbox_inches="tight")
    plt.close(fig)


# -- what the numbers rest on ------------------------------------------------------------------------------
# The scripted participants' responses to the assistance systems are assumptions (cosim/driver/profiles.py):
# every number of a phase with system A or B depends on these profile parameters, a baseline phase on none.
RESPONSE_PARAMETERS = {
    "A": ("a_brake_prob", "a_brake_decel_mps2", "a_brake_duration_s", "a_gap_increase_s", "a_gap_max_s",
          "a_gap_decay_s", "a_refractory_s"),
    "B": ("b_target_gap_s", "b_compliance", "b_adapt_time_s", "b_warning_gain", "b_none_gain", "b_forget_time_s"),
}  # fmt: skip
RESPONSE_SWEEP = "configs/sweeps/driver_response.yaml"
# per-phase numbers that follow from how the driver drives (the rest describe the traffic or the radio)
DRIVER_DEPENDENT = ("time_gap_mean_s", "time_gap_mean_lead_free_s", "time_gap_sd_s", "share_below_2s",
                    "share_below_1s", "warnings", "advisories", "hard_braking_events", "ego_collisions",
                    "min_ttc_s")  # fmt: skip


def response_assumptions(exp) -> dict:
    """Which summary numbers rest on the assumed responses to systems A and B, and the values assumed for
    each scripted participant (profile and ``run.ego.driver.profile_overrides`` of the experiment)."""
    from cosim.driver import DriverConfig

    run = exp.run if isinstance(exp.run, dict) else {}
    driver = (run.get("ego") or {}).get("driver") or {}
    overrides = dict(driver.get("profile_overrides") or {})
    scripted = driver.get("kind", "scripted") == "scripted"
    values: dict[str, dict[str, float]] = {}
    for part in exp.participants:
        if not scripted:
            continue
        prof = DriverConfig(profile=part.profile, profile_overrides=overrides).resolved_profile()
        values[part.id] = {
            name: getattr(prof, name) for names in RESPONSE_PARAMETERS.values() for name in names
        }
    systems = sorted({p.system for p in exp.phases if p.system in RESPONSE_PARAMETERS})
    return {
        "scripted_participants": sorted(values),
        "note": (
            "The scripted participants' responses to systems A and B are assumptions (cosim/driver/"
            "profiles.py), not measured behaviour. In every phase with system A or B the driver-dependent "
            "numbers (and so every A/B-versus-baseline and A-versus-B comparison) rest on them; baseline "
            "phases do not. " + RESPONSE_SWEEP + " shows how the A/B difference moves with them."
            if values
            else "No scripted participant: the responses are the people's own."
        ),
        "parameters": {s: list(RESPONSE_PARAMETERS[s]) for s in systems},
        "profile_overrides": {
            k: v for k, v in overrides.items() if any(k in ns for ns in RESPONSE_PARAMETERS.values())
        },  # fmt: skip
        "values": values,
        "driver_dependent_numbers": list(DRIVER_DEPENDENT),
        "sweep": RESPONSE_SWEEP,
    }


def mark_assumed(results: list[dict], across: list[dict], assumptions: dict) -> None:
    """Give every phase (and every across-participants row) ``rests_on_assumed_response``: the profile
    parameters its driver-dependent numbers depend on ([] for the baseline or a person at the wheel)."""
    scripted = set(assumptions["scripted_participants"])
    for r in results:
        for ph in r["phases"]:
            system = ph.get("system")
            assumed = r["participant"] in scripted and system in RESPONSE_PARAMETERS
            ph["rests_on_assumed_response"] = list(RESPONSE_PARAMETERS[system]) if assumed else []
    for row in across:
        assumed = bool(scripted) and row.get("system") in RESPONSE_PARAMETERS
        row["rests_on_assumed_response"] = list(RESPONSE_PARAMETERS[row["system"]]) if assumed else []


def assumptions_markdown(assumptions: dict) -> list[str]:
    """The summary.md section on the assumed responses."""
    lines = ["## Assumptions: the participants' responses to systems A and B", "", assumptions["note"], ""]
    values = assumptions["values"]
    if not values:
        return lines
    systems = [s for s in ("A", "B") if s in assumptions["parameters"]]
    lines += [
        f"The rows of system {' and '.join(systems)} phases (`rests_on_assumed_response` in summary.json) "
        "depend on these values:",
        "",
    ]
    ids = list(values)
    lines += ["| system | parameter | " + " | ".join(ids) + " |", "|---|---|" + "---|" * len(ids)]
    for s in systems:
        for name in assumptions["parameters"][s]:
            lines.append(f"| {s} | `{name}` | " + " | ".join(f"{values[i][name]:g}" for i in ids) + " |")
    lines += ["", "Numbers that rest on them in those rows: " + ", ".join(assumptions["driver_dependent_numbers"])
              + ". Vary them with `ego.driver.profile_overrides` (a run config, or `run:` of the experiment "
              f"config) or run `cosim sweep {assumptions['sweep']}`.", ""]  # fmt: skip
    return lines
