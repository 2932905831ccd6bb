"""The studio client's stores (``web/src/stores/``) are the only writers of their fields: the other modules read
them and tell a store what happened through its methods (``history.dragEnded()``, ``mesh.connectionLost()`` …).

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

MUTATORS = ("push", "pop", "shift", "unshift", "splice", "sort", "reverse", "fill", "copyWithin")
"""Array methods that change the array they are called on."""


def store_classes() -> dict[str, set[str]]:
    """Each store class and the names of the fields it shows: its getters (and public fields, which it should not
    have)."""
    classes: dict[str, set[str]] = {}
    for path in sorted(STORES.glob("*.js")):
        text = path.read_text(encoding="utf-8")
        for match in re.finditer(r"^export class (\w+) \{\n(.*?)^\}", text, re.M | re.S):
            body = match.group(2)
            classes[match.group(1)] = set(re.findall(r"^  get (\w+)\(\)", body, re.M)) | set(
                re.findall(r"^  (\w+)\s*(?:=|;)", body, re.M)
            )
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


def outside_writes() -> list[str]:
    """Every line outside ``stores/`` that assigns to a store's field (or to a part of it), or changes an array a
    store holds, as ``file:line: text``."""
    classes = store_classes()
    fields = set().union(*classes.values())
    names = store_names(set(classes))
    receiver = rf"\b(?:{'|'.join(sorted(names))})\??\.(?:{'|'.join(sorted(fields))})\b"
    part = r"(?:\??\.\w+|\[[^\]]*\])*"
    write = re.compile(
        rf"{receiver}{part}\s*(?:[-+*/%&|^]?=(?![=>])|\+\+|--)"
        rf"|(?:\+\+|--|\bdelete\s+){receiver}"
        rf"|{receiver}{part}\.(?:{'|'.join(MUTATORS)})\("
    )
    found = []
    for path in client_modules():
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
            if line.lstrip().startswith(("//", "*", "/*")):
                continue
            if write.search(line):
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
