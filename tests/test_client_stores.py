"""The studio client's stores (``web/src/stores/``) are the only writers of their fields: the other modules read
them and tell a store what happened through its methods (``history.dragEnded()``, ``mesh.connectionLost()`` …).
The selection (``Selection``), the pointer tools (``SelectionTools``) and the gizmo's placed pivots and matrices
(``HandleGizmo.pivots``, ``HandleGizmo.matrices``) follow the same rule from their own modules
(``selection.groupChosen(g)``, ``tools.toolChosen(tool)``, ``gizmo.pivotFollowed(g, pivot)``,
``gizmo.setMatrix(g, m)`` …).

A store keeps its state in private fields (``#name``) behind getters, so ``npm run typecheck`` already refuses
an assignment from outside; these tests say the same without Node, and name the line that breaks the rule.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest

WEB_SRC = Path(__file__).resolve().parents[1] / "web" / "src"
STORES = WEB_SRC / "stores"

MUTATORS = ("push", "pop", "shift", "unshift", "splice", "sort", "reverse", "fill", "copyWithin", "set")
"""Array methods that change the array they are called on (``set``: a typed array's)."""

THREE_MUTATORS = ("copy", "identity", "fromArray", "multiply", "premultiply", "multiplyMatrices", "invert",
                  "compose", "applyMatrix4", "applyQuaternion", "setPosition", "makeTranslation", "add", "sub")
"""Methods of the Three.js values fields hold (matrices, vectors) that change the value they are called on."""

OWNERS: dict[str, tuple[str, frozenset[str] | None]] = {
    "Selection": ("selection.js", None),
    "SelectionTools": ("tools.js", None),
    "HandleGizmo": ("gizmo.js", frozenset({"pivots", "matrices"})),
}
"""Classes outside ``stores/`` that are the only writers of fields of theirs, as a store is of its fields: the module
that defines each, and the fields it keeps to itself (None: all it shows)."""


def class_bodies(path: Path) -> dict[str, str]:
    """The body of each class a module exports."""
    text = path.read_text(encoding="utf-8")
    return {m.group(1): m.group(2) for m in re.finditer(r"^export class (\w+) \{\n(.*?)^\}", text, re.M | re.S)}


def shown_fields(body: str) -> set[str]:
    """The fields a class body shows: its getters, its public fields, and the public fields its methods create
    (``this.x = …``)."""
    return (
        set(re.findall(r"^  get (\w+)\(\)", body, re.M))
        | set(re.findall(r"^  (\w+)\s*(?:=|;)", body, re.M))
        | set(re.findall(r"^\s+this\.(\w+)\s*=(?![=>])", body, re.M))
    )


def store_classes() -> dict[str, set[str]]:
    """Each store class and the names of the fields it shows: its getters (and public fields, which it should not
    have)."""
    classes: dict[str, set[str]] = {}
    for path in sorted(STORES.glob("*.js")):
        for name, body in class_bodies(path).items():
            classes[name] = shown_fields(body)
    return classes


def owner_classes() -> dict[str, set[str]]:
    """Each class of OWNERS and the fields it keeps to itself."""
    classes: dict[str, set[str]] = {}
    for name, (module, kept) in OWNERS.items():
        fields = shown_fields(class_bodies(WEB_SRC / module)[name])
        classes[name] = fields & kept if kept is not None else fields
    return classes


def client_modules() -> list[Path]:
    """The client's modules outside the stores."""
    return sorted(p for p in WEB_SRC.glob("*.js") if p.name != "protocol.js")


def store_names(classes: set[str]) -> set[str]:
    """The names the stores go by in the client: the variables they are created in, and the options and properties
    typed as one (``@property {…MeshStore} mesh``, ``@param {MeshStore} opts.mesh``)."""
    alternatives = "|".join(sorted(classes))
    created = re.compile(rf"\b(\w+)\s*=\s*new ({alternatives})\(")
    typed = re.compile(rf"\{{[^{{}}]*\b(?:{alternatives})\}}\s+(?:\w+\.)?(\w+)")
    names: set[str] = set()
    for path in client_modules():
        text = path.read_text(encoding="utf-8")
        names.update(m.group(1) for m in created.finditer(text))
        names.update(m.group(1) for m in typed.finditer(text))
    return names


def write_pattern(names: set[str], fields: set[str], field_aliases: set[str]) -> re.Pattern[str]:
    """A line that assigns to ``name.field`` (or to a part of it), or changes an array it holds; or that writes into
    a local copy of such a field (``const {roi} = selection; roi[i] = 1``)."""
    assign = r"(?:[-+*/%&|^]?=(?![=>])|\+\+|--)"
    part = r"(?:\??\.\w+|\[[^\]]*\])*"
    mutate = rf"\.(?:{'|'.join(MUTATORS + THREE_MUTATORS)})\("
    receiver = rf"\b(?:{'|'.join(sorted(names))})\??\.(?:{'|'.join(sorted(fields))})\b"
    alternatives = [
        rf"{receiver}{part}\s*{assign}",
        rf"(?:\+\+|--|\bdelete\s+){receiver}",
        rf"{receiver}{part}{mutate}",
    ]
    if field_aliases:
        alias = rf"(?<![.\w])(?:{'|'.join(sorted(field_aliases))})"
        alternatives += [rf"{alias}(?:\??\.\w+|\[[^\]]*\])+\s*{assign}", rf"{alias}{part}{mutate}"]
    return re.compile("|".join(alternatives))


def aliases(text: str, names: set[str], fields: set[str]) -> tuple[set[str], set[str]]:
    """The local names a module gives a class's instance (``const s = this.selection;``) and its fields
    (``const {roi, role} = s;``, ``const roi = s.roi;``)."""
    alternatives = "|".join(sorted(names))
    instance = set(re.findall(rf"\b(?:const|let|var)\s+(\w+)\s*=\s*(?:[\w.]*\.)?(?:{alternatives})\s*;", text))
    every = "|".join(sorted(names | instance))
    field_aliases: set[str] = set()
    for group in re.findall(rf"\b(?:const|let|var)\s*\{{([^}}]*)\}}\s*=\s*(?:[\w.]*\.)?(?:{every})\s*;", text):
        for entry in group.split(","):
            source, _, local = entry.partition(":")
            if source.strip() in fields:
                field_aliases.add((local or source).strip())
    element = r"(?:\??\.?\[[^\]]*\])*"  # a field, or an element of it (``const m = gizmo.matrices[g];``)
    for local, field in re.findall(
        rf"\b(?:const|let|var)\s+(\w+)\s*=\s*(?:[\w.]*\.)?(?:{every})\??\.(\w+){element}\s*;", text
    ):
        if field in fields:
            field_aliases.add(local)
    return instance, field_aliases


def outside_writes(classes: dict[str, set[str]] | None = None) -> list[str]:
    """Every line outside ``stores/`` (and outside the module of the class) that assigns to a field of one of
    `classes` (the stores by default) or to a part of it, or changes an array it holds, as ``file:line: text``."""
    if classes is None:
        classes = store_classes()
    homes = {name: module for name, (module, _) in OWNERS.items()}
    names_of = {name: store_names({name}) for name in classes}
    found = []
    for path in client_modules():
        text = path.read_text(encoding="utf-8")
        patterns = []
        for name, fields in sorted(classes.items()):
            names = names_of[name]
            if homes.get(name) == path.name or not fields or not names:
                continue
            instance, field_aliases = aliases(text, names, fields)
            patterns.append(write_pattern(names | instance, fields, field_aliases))
        for number, line in enumerate(text.splitlines(), start=1):
            if line.lstrip().startswith(("//", "*", "/*")):
                continue
            if any(p.search(line) for p in patterns):
                found.append(f"{path.relative_to(WEB_SRC)}:{number}: {line.strip()}")
    return found


def test_the_stores_are_found() -> None:
    classes = store_classes()
    assert {"MeshStore", "HistoryStore", "ParamStore", "Diagnostics", "ToolStore"} <= set(classes)
    for name, getters in classes.items():
        assert getters, f"{name} shows no fields"
    assert {"mesh", "history", "params", "diagnostics"} <= store_names(set(classes))


def test_no_module_writes_a_store_field() -> None:
    found = outside_writes()
    assert not found, "store fields written outside their store (call a method of the store instead):\n" + "\n".join(
        found
    )


def test_a_store_keeps_its_state_in_private_fields() -> None:
    for path in sorted(STORES.glob("*.js")):
        text = path.read_text(encoding="utf-8")
        public_fields = re.findall(r"^  (\w+)\s*(?:=|;)", text, re.M)
        assert not public_fields, f"{path.name}: public fields {public_fields} (keep them private, behind getters)"
        public_writes = re.findall(r"\bthis\.(\w+)(?:\.\w+|\[[^\]]*\])*\s*(?:[-+*/]?=(?![=>])|\+\+|--)", text)
        assert not public_writes, f"{path.name}: writes public fields {public_writes}"


def test_the_scan_sees_the_writes_it_forbids(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The scan itself: a write, a compound assignment, an increment, a nested write and an array change are seen;
    reads, comparisons and the stores' methods are not."""
    src = tmp_path / "src"
    (src / "stores").mkdir(parents=True)
    (src / "stores" / "s.js").write_text(
        "export class HistoryStore {\n  #a = false;\n  get awaitingState() {\n    return this.#a;\n  }\n"
        "  get busyFor() {\n    return null;\n  }\n}\n",
        encoding="utf-8",
    )
    (src / "m.js").write_text(
        "/** @property {import('./stores/s.js').HistoryStore} history */\n"
        "history.awaitingState = true;\n"
        "d.history.busyFor += 'x';\n"
        "history.busyFor++;\n"
        "history.busyFor.x[2] = 1;\n"
        "history.busyFor.push(3);\n"
        "if (history.awaitingState === true) history.dragEnded();\n"
        "const f = (x) => history.awaitingState;\n"
        "// history.awaitingState = false;\n",
        encoding="utf-8",
    )
    module = sys.modules[__name__]
    monkeypatch.setattr(module, "WEB_SRC", src)
    monkeypatch.setattr(module, "STORES", src / "stores")
    assert [w.split(":")[1] for w in outside_writes()] == ["2", "3", "4", "5", "6"]


def test_the_owners_are_found() -> None:
    classes = owner_classes()
    assert {"activeGroup", "groups", "roi", "role", "stiff", "stiffnessValue", "version"} <= classes["Selection"]
    assert {"tool", "units", "radiusPx", "worldRadiusFrac", "frontOnly", "metric"} <= classes["SelectionTools"]
    assert classes["HandleGizmo"] == {"pivots", "matrices"}
    assert {"selection", "tools", "gizmo"} <= store_names(set(classes))


def test_no_module_writes_the_selection_the_tools_or_the_pivots() -> None:
    found = outside_writes(owner_classes())
    assert not found, "fields written outside the module of their class (call a method of it instead):\n" + "\n".join(
        found
    )


@pytest.mark.parametrize("name", sorted(OWNERS))
def test_an_owner_keeps_its_fields_private(name: str) -> None:
    module, kept = OWNERS[name]
    body = class_bodies(WEB_SRC / module)[name]
    public_fields = set(re.findall(r"^  (\w+)\s*(?:=|;)", body, re.M))
    public_writes = set(re.findall(r"\bthis\.(\w+)(?:\.\w+|\[[^\]]*\])*\s*(?:[-+*/]?=(?![=>])|\+\+|--)", body))
    if kept is not None:
        public_fields &= kept
        public_writes &= kept
        assert kept <= set(re.findall(r"^  get (\w+)\(\)", body, re.M)), f"{module}: no getters for {sorted(kept)}"
    assert not public_fields, f"{module}: {name} has public fields {sorted(public_fields)} (keep them private)"
    assert not public_writes, f"{module}: {name} writes public fields {sorted(public_writes)}"


def _scanned(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, owners: dict[str, tuple[str, frozenset[str] | None]],
             files: dict[str, str]) -> list[list[str]]:
    """The outside writes (file and line) the scan finds in a source folder of ``files`` with ``owners``."""
    src = tmp_path / "src"
    (src / "stores").mkdir(parents=True)
    for name, text in files.items():
        (src / name).write_text(text, encoding="utf-8")
    module = sys.modules[__name__]
    monkeypatch.setattr(module, "WEB_SRC", src)
    monkeypatch.setattr(module, "STORES", src / "stores")
    monkeypatch.setattr(module, "OWNERS", owners)
    return [w.split(":")[:2] for w in outside_writes(owner_classes())]


def test_the_scan_follows_local_names(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Writes through a local name of the instance or of one of its fields are seen; writes in the class's own
    module, to other fields, and rebinding a local name are not."""
    sel = ("export class Selection {\n  #g = 0;\n  get activeGroup() {\n    return this.#g;\n  }\n"
           "  get roi() {\n    return this.#g;\n  }\n}\n"
           "const selection = new Selection();\nselection.activeGroup = 2;\n")
    m = (
        "/** @param {import('./sel.js').Selection} selection */\n"
        "const s = this.selection;\n"
        "s.activeGroup = 1;\n"
        "s.roi.fill(0);\n"
        "const { roi, other } = s;\n"
        "roi[3] = 1;\n"
        "other[3] = 1;\n"
        "let r = s.roi;\n"
        "r.set([1]);\n"
        "r = null;\n"
        "s.partnerOf(1).x = 2;\n"
    )
    assert _scanned(tmp_path, monkeypatch, {"Selection": ("sel.js", None)}, {"sel.js": sel, "m.js": m}) == [
        ["m.js", "3"],
        ["m.js", "4"],
        ["m.js", "6"],
        ["m.js", "9"],
    ]


def test_the_scan_sees_a_matrix_changed_in_place(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A kept field's Three.js values changed in place (``gizmo.matrices[g].copy(m)``, or through a local name of an
    element) are writes; computing from them (``.clone().invert()``, ``.elements``) and the gizmo's method are not."""
    gizmo = ("export class HandleGizmo {\n  #m = [];\n  get matrices() {\n    return this.#m;\n  }\n"
             "  setMatrix(g, m) {\n    this.#m[g]?.copy(m);\n  }\n}\n")
    mirror = (
        "/** @param {import('./gizmo.js').HandleGizmo} gizmo */\n"
        "gizmo.matrices[p].multiplyMatrices(this.matrix, T).multiply(this.matrix);\n"
        "const m = gizmo.matrices[turning.group];\n"
        "m.copy(turned);\n"
        "gizmo.matrices[0].identity();\n"
        "const inverse = gizmo.matrices[g].clone().invert();\n"
        "const e = Array.from(gizmo.matrices[g].elements);\n"
        "gizmo.setMatrix(p, new THREE.Matrix4().multiplyMatrices(a, b));\n"
    )
    owners = {"HandleGizmo": ("gizmo.js", frozenset({"matrices"}))}
    assert _scanned(tmp_path, monkeypatch, owners, {"gizmo.js": gizmo, "mirror.js": mirror}) == [
        ["mirror.js", "2"],
        ["mirror.js", "4"],
        ["mirror.js", "5"],
    ]
