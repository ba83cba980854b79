"""The simulator boundary, checked on the source tree (ast, not timing): ``cosim.sumo_bridge`` is the only
code that talks to SUMO, sumolib included.

The rule: no module of the ``cosim`` package outside ``cosim/sumo_bridge/`` imports libsumo, traci or
sumolib, at module level or inside a function, and none reaches the bridge's backend handle (``.sumo`` /
``._sumo`` of a bridge). There is no build-time exception: the scenario build reads the networks
netconvert wrote through ``cosim.sumo_bridge.network.read_network`` like the run does (netconvert and the
other SUMO binaries run as subprocesses, located by ``cosim.sumo_bridge.tools``). Tests, benchmarks and
examples are outside the package and may use libsumo directly.

The phases given narrow ports (issue 19) do not take the Simulation: no method of theirs (constructor,
``step`` and the ego's other schedule entries) has a ``sim`` parameter or names ``sim``, each has ``step``
and ``close``, and their modules never import ``cosim.sim``.
"""

from __future__ import annotations

import ast
from pathlib import Path

import cosim

PKG = Path(cosim.__file__).parent
SIMULATORS = {"libsumo", "traci", "sumolib"}
BRIDGE = PKG / "sumo_bridge"
PORTED = {  # module -> classes whose methods take ports, not the Simulation
    "phases/traffic.py": ("TrafficAroundEgo",),
    "phases/route.py": ("EgoRoute",),
    "phases/vanet.py": ("VanetPhase",),
    "phases/adas.py": ("AdasPhase",),
    "phases/ego.py": ("EgoController",),
    "phases/lead.py": ("LeadVehicle",),
    "health.py": ("DriveHealth",),
    "log/recorder.py": ("Recorder",),
}


def _modules():
    for path in sorted(PKG.rglob("*.py")):
        yield path, ast.parse(path.read_text(), filename=str(path))


def _imported(tree: ast.AST) -> list[tuple[int, str]]:
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            out.append((node.lineno, node.module))
    return out


def test_the_source_tree_is_found():
    files = [p for p, _ in _modules()]
    assert PKG / "sim.py" in files and BRIDGE / "bridge.py" in files and len(files) > 50


def test_only_the_bridge_imports_a_simulator():
    offenders = []
    for path, tree in _modules():
        if BRIDGE in path.parents:
            continue
        for line, name in _imported(tree):
            if name.split(".")[0] in SIMULATORS:
                offenders.append(f"{path.relative_to(PKG.parent)}:{line} imports {name}")
    assert not offenders, "\n".join(offenders)


def test_the_bridge_does_import_them():
    names = {n.split(".")[0] for p, t in _modules() if BRIDGE in p.parents for _, n in _imported(t)}
    assert SIMULATORS <= names  # otherwise the test above would check nothing


def test_nothing_outside_the_bridge_reaches_its_backend_handle():
    offenders = []
    for path, tree in _modules():
        if BRIDGE in path.parents:
            continue
        for node in ast.walk(tree):
            if isinstance(node, ast.Attribute) and node.attr in ("sumo", "_sumo"):
                base = node.value
                name = base.attr if isinstance(base, ast.Attribute) else getattr(base, "id", "")
                if "bridge" in name.lower():
                    offenders.append(f"{path.relative_to(PKG.parent)}:{node.lineno} uses {name}.{node.attr}")
    assert not offenders, "\n".join(offenders)


def test_ported_phases_take_ports_not_the_simulation():
    for rel, classes in PORTED.items():
        tree = ast.parse((PKG / rel).read_text())
        assert "cosim.sim" not in {n for _, n in _imported(tree)}, rel
        found = {c.name: c for c in ast.walk(tree) if isinstance(c, ast.ClassDef)}
        for cls in classes:
            methods = {f.name: f for f in found[cls].body if isinstance(f, ast.FunctionDef)}
            assert "step" in methods and "close" in methods, (rel, cls)
            for name, method in methods.items():
                args = method.args
                params = [a.arg for a in args.posonlyargs + args.args + args.kwonlyargs]
                assert "sim" not in params, f"{rel}: {cls}.{name} takes the Simulation"
            names = {n.id for n in ast.walk(found[cls]) if isinstance(n, ast.Name)}
            attrs = {n.attr for n in ast.walk(found[cls]) if isinstance(n, ast.Attribute)}
            assert "sim" not in names | attrs, f"{rel}: {cls} reaches the Simulation"
