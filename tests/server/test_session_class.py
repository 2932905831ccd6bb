"""The studio session is one class that owns its state: every attribute declared once, with its type and a line of
doc, in ``Session.__init__``; set by the session's own methods only, never by the server's other modules; and its
solver typed (never ``Any``) wherever the server hands one around. Read from the source with :mod:`ast`."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np

import arap
import arap.server
from arap.server.session import Session
from arap.server.solvers import PlaneSolver, plane_solver

SERVER = Path(arap.server.__file__).parent
SESSION = SERVER / "session.py"
PACKAGE = Path(arap.__file__).parent
SOLVER_USERS = [PACKAGE / "animation.py", PACKAGE / "batching" / "worker.py", PACKAGE / "puppet" / "warp.py"]
"""Modules outside the server that hand solvers around."""


def _parse(path: Path) -> ast.Module:
    return ast.parse(path.read_text(encoding="utf-8"), filename=str(path))


def _session_class() -> ast.ClassDef:
    found = [n for n in _parse(SESSION).body if isinstance(n, ast.ClassDef) and n.name == "Session"]
    assert len(found) == 1
    return found[0]


def _stored(node: ast.AST) -> list[ast.Attribute]:
    """The attributes an assignment statement (of any kind) stores to, tuple targets unpacked."""
    if isinstance(node, ast.Assign):
        targets = list(node.targets)
    elif isinstance(node, ast.AugAssign | ast.AnnAssign):
        targets = [node.target]
    else:
        return []
    found: list[ast.Attribute] = []
    while targets:
        t = targets.pop()
        if isinstance(t, ast.Tuple | ast.List):
            targets.extend(t.elts)
        elif isinstance(t, ast.Starred):
            targets.append(t.value)
        elif isinstance(t, ast.Attribute):
            found.append(t)
    return found


def _on_self(attribute: ast.Attribute) -> bool:
    return isinstance(attribute.value, ast.Name) and attribute.value.id == "self"


def _init() -> ast.FunctionDef:
    init = [n for n in _session_class().body if isinstance(n, ast.FunctionDef) and n.name == "__init__"]
    assert init, "Session has no __init__ of its own"
    return init[0]


def _declared() -> dict[str, ast.AnnAssign]:
    """The attributes ``Session.__init__`` declares, by name (the first declaration of each)."""
    declared: dict[str, ast.AnnAssign] = {}
    for node in _init().body:
        if isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Attribute) and _on_self(node.target):
            declared.setdefault(node.target.attr, node)
    return declared


def _is_any(annotation: ast.expr | None) -> bool:
    """Whether an annotation is ``Any``, or a union with ``Any`` in it (``Any | None``)."""
    if annotation is None:
        return False
    if isinstance(annotation, ast.Constant) and isinstance(annotation.value, str):
        return _is_any(ast.parse(annotation.value, mode="eval").body)
    if isinstance(annotation, ast.BinOp) and isinstance(annotation.op, ast.BitOr):
        return _is_any(annotation.left) or _is_any(annotation.right)
    if isinstance(annotation, ast.Subscript) and ast.unparse(annotation.value).split(".")[-1] == "Optional":
        return _is_any(annotation.slice)
    return ast.unparse(annotation).split(".")[-1] == "Any"


def test_the_session_is_one_class_in_one_module() -> None:
    assert Session.__mro__ == (Session, object)
    assert Session.__module__ == "arap.server.session"
    assert not (SERVER / "session_state.py").exists()


def test_every_attribute_is_declared_once_in_init_with_its_type_and_doc() -> None:
    init = _init()
    names: list[str] = []
    for k, node in enumerate(init.body):
        for attribute in _stored(node):
            assert _on_self(attribute)
            assert isinstance(node, ast.AnnAssign), f"self.{attribute.attr} is declared without its type"
            names.append(attribute.attr)
            after = init.body[k + 1] if k + 1 < len(init.body) else None
            documented = (isinstance(after, ast.Expr) and isinstance(after.value, ast.Constant)
                          and isinstance(after.value.value, str))
            assert documented, f"self.{attribute.attr} is declared without a line of doc"
    assert len(names) == len(set(names)), "an attribute is declared twice"
    assert set(names) == set(vars(Session())), "the attributes a new session has are the ones __init__ declares"


def test_the_session_sets_only_the_attributes_it_declares() -> None:
    declared = _declared()
    properties = {n.name for n in _session_class().body if isinstance(n, ast.FunctionDef)
                  and any(ast.unparse(d) == "property" for d in n.decorator_list)}
    undeclared = []
    for node in ast.walk(_session_class()):
        for attribute in _stored(node):
            if _on_self(attribute) and attribute.attr not in declared:
                undeclared.append(f"line {attribute.lineno}: self.{attribute.attr}")
        if isinstance(node, ast.Call) and ast.unparse(node.func) in ("getattr", "setattr", "hasattr"):
            undeclared.append(f"line {node.lineno}: {ast.unparse(node)}")
    assert undeclared == []
    assert not properties & set(declared)


def test_no_other_module_of_the_server_sets_a_session_attribute() -> None:
    """Neither through a name for a session (``session.energy = ...``, ``self.session.U = ...``, ``state.V = ...``)
    nor as ``self`` in a class of its own named for sessions (a base class of the session elsewhere)."""
    attributes = set(vars(Session())) | {n for n in dir(Session) if not n.startswith("__")}
    found = []
    for path in sorted(SERVER.glob("*.py")):
        if path == SESSION:
            continue
        tree = _parse(path)
        in_session_classes = {id(node) for cls in ast.walk(tree) if isinstance(cls, ast.ClassDef)
                              and cls.name.lower().startswith("session") for node in ast.walk(cls)}
        for node in ast.walk(tree):
            for attribute in _stored(node):
                base = ast.unparse(attribute.value)
                name = base.rpartition(".")[2].lower()
                a_session = ("session" in name or name in ("sess", "state")) if not _on_self(attribute) \
                    else id(node) in in_session_classes
                if a_session and attribute.attr in attributes:
                    found.append(f"{path.name}:{node.lineno}: {base}.{attribute.attr}")
    assert found == []


def test_no_solver_of_the_server_is_typed_any() -> None:
    found = []
    for path in [*sorted(SERVER.glob("*.py")), *SOLVER_USERS]:
        for node in ast.walk(_parse(path)):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                a = node.args
                for arg in [*a.posonlyargs, *a.args, *a.kwonlyargs]:
                    if "solver" in arg.arg.lower() and _is_any(arg.annotation):
                        found.append(f"{path.name}:{node.lineno}: argument {arg.arg} of {node.name}")
                if "solver" in node.name.lower() and _is_any(node.returns):
                    found.append(f"{path.name}:{node.lineno}: what {node.name} returns")
            elif isinstance(node, ast.AnnAssign) and "solver" in ast.unparse(node.target).lower() \
                    and _is_any(node.annotation):
                found.append(f"{path.name}:{node.lineno}: {ast.unparse(node.target)}")
    assert found == []


def test_a_pictures_solver_delegates_only_what_it_names() -> None:
    """:class:`PlaneSolver` names the inner solver's attributes it gives (typed), and no others pass through."""
    assert "__getattr__" not in vars(PlaneSolver)
    V = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    F = np.array([[0, 1, 2], [0, 2, 3]])
    inner = arap.ArapSolver(V, F, [0, 2], energy="elements")
    solver = plane_solver(inner, "rigid")
    assert solver.energy_type == "elements" and solver.n_free == inner.n_free == 2
    np.testing.assert_array_equal(solver.V, V)
    np.testing.assert_array_equal(solver.F, F)
    assert not hasattr(solver, "fit_rotations")  # the inner solver's, not the picture's
    result = solver.solve(np.array([[0.0, 0, 0], [1.2, 1.1, 0.5]]))
    assert np.abs(result.vertices[:, 2]).max() == 0.0  # the targets are put back on the plane
