"""The studio client's ``main.js`` builds each piece after the pieces it needs, so no piece is reached through a
forward reference (a thunk like ``panel: () => panel`` or a callback naming a piece built further down): a piece
that must tell one built after it emits one of the studio's events (``events.js``) instead.
"""

from __future__ import annotations

import re
from pathlib import Path

MAIN = Path(__file__).resolve().parents[1] / "web" / "src" / "main.js"

ALLOWED = {("keeper", "loading")}
"""(piece, the later piece it names): the session keeper puts a saved session back by loading its mesh, and the
mesh loading asks the keeper before it replaces the mesh shown; the keeper is built first."""

DECLARATION = re.compile(r"^(?:/\*\*.*?\*/\s*)?(?:const|let) (?:\{\s*([\w\s,]+)\}|(\w+))\s*=")


def forward_references(text: str) -> list[tuple[int, str, str]]:
    """Each (line, name, the piece being built) where a top-level ``const`` or ``let`` of main.js is named before the
    line that declares it (comments and imports left out)."""
    lines = text.splitlines()
    declared: dict[str, int] = {}
    for number, line in enumerate(lines, start=1):
        match = DECLARATION.match(line)
        if match:
            for name in (match.group(1) or match.group(2)).split(","):
                declared.setdefault(name.strip(), number)
    found = []
    building = ""
    for number, line in enumerate(lines, start=1):
        match = DECLARATION.match(line)
        if match:
            building = (match.group(1) or match.group(2)).split(",")[0].strip()
        code = line.split("//")[0]
        if code.lstrip().startswith(("*", "/*", "import ")):
            continue
        for name, at in declared.items():
            if number < at and re.search(rf"(?<![\w.]){name}\b(?!\s*:)", code):
                found.append((number, name, building))
    return found


def test_main_builds_each_piece_after_the_pieces_it_needs() -> None:
    found = [f for f in forward_references(MAIN.read_text(encoding="utf-8")) if (f[2], f[1]) not in ALLOWED]
    assert not found, "main.js names pieces before building them (build them first, or emit an event):\n" + "\n".join(
        f"main.js:{number}: {name} (while building {building})" for number, name, building in found
    )


def test_the_scan_sees_forward_references() -> None:
    text = (
        "import { Panel } from './panel.js';\n"
        "const requests = new Requests({ panel: () => panel });\n"
        "const sync = new Sync({ told: (t) => panel.say(t), name: 1 });\n"
        "const panel = new Panel(); // panel\n"
        "const tools = new Tools({ panel });\n"
    )
    assert forward_references(text) == [(2, "panel", "requests"), (3, "panel", "sync")]
