"""The VANET phase in a second process, so that a run uses both cores (issue 20).

``begin`` sends the step's snapshot and waits only for what the assistance phase reads this step: the
ego's OBU view and the station ids, final once the last step's deliveries are in and the stations of this
one are known (``VanetLayer.step``'s ``on_view``). The radio process then generates the CAMs, runs the
medium access, evaluates the channel and builds the log columns of the step while this process runs the
driver, the ego and SUMO's next step; ``finish`` collects them
(``cosim.sim`` logs the step then). Same code, same inputs, same random stream: the results are those of
``VanetPhase`` to the bit (tests/integration/test_radio_process.py).

Libsumo holds the GIL while SUMO steps, so a thread could not overlap the two.
"""

from __future__ import annotations

import pickle
import subprocess
import traceback
from pathlib import Path

import numpy as np

from cosim.childproc import send, serve_stdio, signals_held, start_child
from cosim.phases.vanet import VanetPhase, vehicle_of_station
from cosim.vanet import VanetParams, VanetStepResult
from cosim.vanet.obu import RECORD_FIELDS, ObuView
from cosim.world import World

# what the radio reads of a World (cosim.vanet.layer, cosim.phases.vanet)
_SNAPSHOT_ARRAYS = ("valid", "is_ego", "depart_step", "x_m", "y_m", "heading_deg", "speed_mps", "accel_mps2",
                    "length_m", "width_m", "lane_index", "signals")  # fmt: skip


class Snapshot:
    """A copy of what the radio reads of a World (the World changes in place while the radio works)."""

    def __init__(self, world: World):
        cap = world.capacity
        self.capacity, self.step, self.ego_slot = cap, world.step, world.ego_slot
        for name in _SNAPSHOT_ARRAYS:
            setattr(self, name, getattr(world, name)[:cap].copy())


class HeardRecords:
    """The stored CAMs one OBU view holds (the newest it decoded from each sender), standing in for the
    layer's whole RecordStore: ``held`` and ``get`` answer as the store does for that view."""

    def __init__(self, store, seqs: np.ndarray, now_us: int):
        self.seqs = np.sort(seqs[store.held(seqs, now_us)])
        self.rows = store.data[self.seqs % store.cap]

    def held(self, seqs: np.ndarray, now_us: int) -> np.ndarray:
        return np.isin(seqs, self.seqs)

    def get(self, seqs: np.ndarray) -> dict[str, np.ndarray]:
        rec = self.rows[np.searchsorted(self.seqs, np.asarray(seqs, dtype=np.int64))]
        return {name: rec[name] for name in RECORD_FIELDS}


def portable_view(view: ObuView | None) -> ObuView | None:
    """``view`` with only the records it holds (a few kB instead of the store's MBs)."""
    if view is None:
        return None
    records = HeardRecords(view.records, view.heard_row, view.now_us)
    heard = view.heard_row[records.held(view.heard_row, view.now_us)]  # the same seqs in the same order
    return ObuView(records, heard, view.now_us, view.own, view.params, view.frame_us, view.receiver_slot)


class VanetProcess:
    """``VanetPhase``'s interface (begin, finish, ego_obu, vehicle_of_station, close), run by a child."""

    def __init__(self, params: VanetParams, buildings_file: str | Path, rng: np.random.Generator, *, log: bool,
                 map_store: Path | None = None):  # fmt: skip
        self._proc: subprocess.Popen | None = start_child(
            "from cosim.phases.vanet_process import serve; serve()", replies=True
        )
        self._awaiting: list[str] = []  # the replies due, in order
        self._got: dict[str, tuple] = {}  # replies read and not yet taken
        self._view: ObuView | None = None
        self._station_id = np.zeros(0, dtype=np.uint32)
        self._send((params, str(buildings_file), rng, log, map_store))

    def begin(self, world: World, step_s: float) -> None:
        """Start the step on a copy of the snapshot; returns once the ego's OBU view of the step is here."""
        if self._awaiting:
            raise RuntimeError("vanet: a radio step began before the last one finished")
        self._send((Snapshot(world), step_s))
        self._awaiting = ["view", "result"]
        self._view, self._station_id = self._take("view")

    def finish(self) -> tuple[VanetStepResult, dict[str, object]] | None:
        """The step's result and log messages (None when no step is under way)."""
        if "result" not in self._awaiting and "result" not in self._got:
            return None
        return self._take("result")

    def ego_obu(self, world: World) -> ObuView | None:
        return self._view

    def vehicle_of_station(self, world: World, station: int | None) -> str:
        return vehicle_of_station(world, self._station_id, station)

    def close(self) -> None:
        proc, self._proc = self._proc, None
        if proc is None:
            return
        try:
            proc.stdin.close()  # end of input: the radio process ends
            proc.wait(timeout=30)
        except (OSError, subprocess.TimeoutExpired):
            proc.kill()
            proc.wait()
        finally:
            proc.stdout.close()

    # -- the pipe --------------------------------------------------------------------------------------------
    def _send(self, record) -> None:
        try:
            send(self._proc.stdin, record)
        except (BrokenPipeError, OSError):
            raise RuntimeError("the radio process stopped (its error is above)") from None

    def _take(self, kind: str) -> tuple:
        """The payload of the next reply of ``kind`` (read in order; a Ctrl-C waits until a reply is in)."""
        while kind not in self._got:
            with signals_held():  # read and filed as one: an interrupt never loses a reply
                try:
                    reply = pickle.load(self._proc.stdout)
                except (EOFError, pickle.UnpicklingError, OSError):
                    raise RuntimeError("the radio process stopped (its error is above)") from None
                if reply[0] == "error":
                    raise RuntimeError(f"the radio process failed: {reply[1]}")
                self._awaiting.remove(reply[0])
                self._got[reply[0]] = reply[1:]
        return self._got.pop(kind)


def serve() -> None:
    """The radio process: VanetPhase steps on the snapshots from stdin; replies on a private stdout."""
    stdin, replies = serve_stdio()
    try:
        from cosim.scenario.buildings import indexed_buildings

        params, buildings_file, rng, log, map_store = pickle.load(stdin)
        phase = VanetPhase(params, indexed_buildings(buildings_file), rng, log=log, map_store=map_store)
        while True:
            try:
                world, step_s = pickle.load(stdin)
            except EOFError:  # the run is over
                phase.close()
                break

            def view_ready(world=world) -> None:
                layer = phase.layer
                send(
                    replies,
                    ("view", portable_view(layer.obu_view(world)), layer.station_id[: world.capacity].copy()),
                )

            send(replies, ("result", *phase.step(world, step_s, on_view=view_ready)))
    except BaseException as exc:
        traceback.print_exc()  # on the run's stderr; the run raises the last line
        send(replies, ("error", "".join(traceback.format_exception_only(exc)).strip()))
        raise SystemExit(1) from None
