"""No new import circles in the package: the module graph (top-level and function-level imports) of
``mission`` and ``sitl`` has no strongly connected component beyond the circles still waiting to be
broken; the runtime (what ``localize`` and ``fly-mission`` run) never imports the workshop
(``mission.workshop``); and the localizer (``mission.localize`` and every module it reaches) imports
neither the simulator (``mission.simulate``) nor the mission parser (``mission.spec``): a network's
training facts are read from its card; nor does it reach up into the command layer
(``mission.cli``): what both print through lives below them (``mission.console``)."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

# circles known when this test was written, each to be broken by moving the shared piece down
# (remove an entry when it is gone; the test fails on any circle that is not inside one of these).
# None is left.
KNOWN: tuple[set[str], ...] = ()

# the runtime rooms; with every module that ``localize`` / ``fly-mission`` reach from their CLI
# modules
RUNTIME_PACKAGES = (
    "mission.localize",
    "mission.flight",
    "mission.flightlog",
    "mission.physics",
    "mission.trajectory",
)
RUNTIME_ENTRIES = ("mission.cli.localize", "mission.cli.fly")
WORKSHOP = "mission.workshop"
# what the localizer never reaches: it reads a network's training domain from the card written at
# training time (``localize --at`` also reaches the adaptive planner, part of the flight, which
# builds mission specs)
LOCALIZE_FORBIDDEN = ("mission.simulate", "mission.spec", WORKSHOP, "mission.cli")


def import_graph(root: Path) -> dict[str, set[str]]:
    """Module -> the package modules it imports anywhere in its source (``from a.b import c`` counts
    ``a.b`` and, when it is a module, ``a.b.c``; a package's own ``__init__`` is not an edge of its
    submodules)."""
    files = [*root.glob("mission/**/*.py"), *root.glob("sitl/**/*.py")]
    mods = {}
    for p in files:
        parts = p.relative_to(root).with_suffix("").parts
        mods[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = p
    graph: dict[str, set[str]] = {m: set() for m in mods}
    for m, p in mods.items():
        for node in ast.walk(ast.parse(p.read_text(), str(p))):
            if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                names = [node.module, *(f"{node.module}.{a.name}" for a in node.names)]
            elif isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            else:
                continue
            graph[m] |= {n for n in names if n in mods and n != m and not m.startswith(n + ".")}
    return graph


def circles(graph: dict[str, set[str]]) -> list[set[str]]:
    """Strongly connected components with more than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[set[str]] = []
    for start in graph:
        if start in index:
            continue
        work = [(start, iter(sorted(graph[start])))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = len(index)
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(sorted(graph[w]))))
                elif w in on_stack:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = set()
                while True:
                    x = stack.pop()
                    on_stack.discard(x)
                    comp.add(x)
                    if x == v:
                        break
                if len(comp) > 1:
                    found.append(comp)
    return found


def reachable(graph: dict[str, set[str]], starts) -> set[str]:
    """Every module reachable from ``starts`` along import edges (the starts included)."""
    seen: set[str] = set()
    todo = list(starts)
    while todo:
        m = todo.pop()
        if m not in seen:
            seen.add(m)
            todo.extend(graph[m] - seen)
    return seen


def workshop_imports(graph: dict[str, set[str]]) -> dict[str, list[str]]:
    """Runtime module -> the workshop modules it imports (empty when the arrow points workshop ->
    runtime only)."""
    in_room = [m for m in graph if any(m == p or m.startswith(p + ".") for p in RUNTIME_PACKAGES)]
    runtime = reachable(graph, [*in_room, *RUNTIME_ENTRIES])
    runtime = {m for m in runtime if not (m == WORKSHOP or m.startswith(WORKSHOP + "."))}
    out = {
        m: sorted(w for w in graph[m] if w == WORKSHOP or w.startswith(WORKSHOP + "."))
        for m in runtime
    }
    return {m: ws for m, ws in sorted(out.items()) if ws}


def _inside(m: str, packages) -> bool:
    return any(m == p or m.startswith(p + ".") for p in packages)


def localizer_imports(graph: dict[str, set[str]]) -> dict[str, list[str]]:
    """Module the localizer reaches -> the simulator / mission-parser / workshop modules it
    imports."""
    starts = [m for m in graph if _inside(m, ("mission.localize",))]
    reached = {m for m in reachable(graph, starts) if not _inside(m, LOCALIZE_FORBIDDEN)}
    out = {m: sorted(w for w in graph[m] if _inside(w, LOCALIZE_FORBIDDEN)) for m in reached}
    return {m: ws for m, ws in sorted(out.items()) if ws}


def test_circle_finder_on_a_known_graph() -> None:
    g = {"a": {"b"}, "b": {"c"}, "c": {"a", "d"}, "d": set(), "f": {"g"}, "g": {"f"}}
    assert sorted(map(sorted, circles(g))) == [["a", "b", "c"], ["f", "g"]]
    assert circles({"a": {"b"}, "b": set()}) == []


def test_no_new_import_circles(repo_dir) -> None:
    graph = import_graph(repo_dir)
    assert "mission.trajectory.multicopter" in graph["mission.trajectory.attitude"]
    new = [sorted(c) for c in circles(graph) if not any(c <= k for k in KNOWN)]
    assert not new, f"new import circle(s): {new}"


def test_reachable_on_a_known_graph() -> None:
    g = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}, "e": set()}
    assert reachable(g, ["a"]) == {"a", "b", "c"}
    assert reachable(g, ["d", "e"]) == {"a", "b", "c", "d", "e"}


def test_runtime_never_imports_the_workshop(repo_dir) -> None:
    graph = import_graph(repo_dir)
    runtime = reachable(graph, RUNTIME_ENTRIES)
    # the entries reach what they run
    assert {"mission.localize.api", "mission.flight.runner", "mission.adaptive.rounds"} <= runtime
    assert (
        "mission.workshop.suite" in graph
        and "mission.localize.api" in graph["mission.workshop.evaluate"]
    )
    assert not workshop_imports(graph), (
        f"runtime module(s) import the workshop: {workshop_imports(graph)}"
    )
    # the check sees an edge added anywhere the CLI reaches, even outside the runtime packages
    graph["mission.flight.live"] = graph["mission.flight.live"] | {"mission.workshop.suite"}
    assert workshop_imports(graph) == {"mission.flight.live": ["mission.workshop.suite"]}


def test_the_localizer_imports_neither_simulator_nor_mission_parser(repo_dir) -> None:
    graph = import_graph(repo_dir)
    assert {
        "mission.localize.training_domain",
        "mission.localize.card",
        "mission.geo",
    } <= reachable(graph, ["mission.localize.api"])
    assert not localizer_imports(graph), f"the localizer imports: {localizer_imports(graph)}"
    # the check sees an edge added anywhere localize reaches, the way training_domain once reached
    # both
    graph["mission.localize.training_domain"] = graph["mission.localize.training_domain"] | {
        "mission.spec"
    }
    graph["mission.geo"] = graph["mission.geo"] | {"mission.simulate"}
    # and the command layer, the way matched.py once took its console from mission.cli.main
    graph["mission.localize.matched"] = graph["mission.localize.matched"] | {"mission.cli.main"}
    assert localizer_imports(graph) == {
        "mission.geo": ["mission.simulate"],
        "mission.localize.matched": ["mission.cli.main"],
        "mission.localize.training_domain": ["mission.spec"],
    }


def test_architecture_map_names_every_module_in_its_room(repo_dir) -> None:
    """ARCHITECTURE.md's row of each room names every module that lives there (and none from the
    other room)."""
    rows = {
        ln.split("|")[1].strip(): ln
        for ln in (repo_dir / "ARCHITECTURE.md").read_text().splitlines()
        if ln.startswith("| `mission/")
    }
    rooms = {
        room: sorted(
            p.name for p in (repo_dir / "mission" / room).glob("*.py") if p.name != "__init__.py"
        )
        for room in ("localize", "workshop")
    }
    for room, files in rooms.items():
        row = rows[f"`mission/{room}/`"]
        assert files and not [f for f in files if f"`{f}`" not in row], (
            f"mission/{room}/ row misses modules"
        )
        other = rooms["workshop" if room == "localize" else "localize"]
        assert not [f for f in other if f"`{f}`" in row], (
            f"mission/{room}/ row names the other room's modules"
        )


# libraries only some localize routes use: imported where those routes need them, so that
# ``localize --method grid`` starts without them (it started 0.7-0.9 s slower when api.py reached
# them at load)
OTHER_ROUTES_ONLY = ("scipy.stats", "onnxruntime", "contourpy", "scipy.spatial")


def test_the_localize_entry_loads_no_other_routes_library(repo_dir) -> None:
    code = (
        "import sys, mission.cli.localize, mission.localize.api, mission.localize.classical; "
        f"print(sorted(m for m in {OTHER_ROUTES_ONLY!r} if m in sys.modules))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], cwd=repo_dir, capture_output=True, text=True, check=True
    )
    assert out.stdout.strip() == "[]", f"loaded at import: {out.stdout.strip()}"
