"""The example notebook runs from top to bottom in a fresh kernel (Run All), the inline studio (a widget) included,
and leaves the studio running for the reader to edit."""

from __future__ import annotations

from pathlib import Path

import nbformat
import pytest
from nbclient import NotebookClient

pytestmark = pytest.mark.timeout(240)

NOTEBOOK = Path(__file__).resolve().parents[2] / "docs" / "notebooks" / "first-deformation.ipynb"


def test_example_notebook_runs_all_and_leaves_the_studio_open(tmp_path: Path) -> None:
    nb = nbformat.read(NOTEBOOK, as_version=4)
    client = NotebookClient(nb, timeout=180, kernel_name="python3", resources={"metadata": {"path": str(tmp_path)}})
    with client.setup_kernel():
        for index, cell in enumerate(nb.cells):  # Run All: one cell after the other, nobody waiting in between
            client.execute_cell(cell, index)
        after = nbformat.v4.new_code_cell("print(f'running after Run All: {studio.running} {studio.wait(60)}')")
        nb.cells.append(after)
        client.execute_cell(after, len(nb.cells) - 1)
    outputs = [o for cell in nb.cells if cell.cell_type == "code" for o in cell.outputs]
    assert not [o for o in outputs if o.output_type == "error"]
    # a stream may arrive in several outputs, split anywhere (the kernel flushes on a timer): join those as written
    text = "".join(str(o.get("text", "")) if o.output_type == "stream" else "\n" + str(o.get("data", {}).get(
        "text/plain", "")) + "\n" for o in outputs)
    assert "converged: True" in text
    assert "(True," in text  # the energies never rose
    assert "running after Run All: True True" in text  # the studio is left for the reader, not stopped
    assert "largest displacement: 0.000" in text  # the last cell read the shape back (the rest shape: no drag yet)
    plots = [o for o in outputs if "image/png" in o.get("data", {})]
    pictures = [o for o in plots if str(o["data"].get("text/plain", "")).startswith("Picture(")]
    assert len(pictures) == 2 and len(pictures[0]["data"]["image/png"]) > 5_000  # rest | bent, and the result
    kept = [o for o in plots if "studio's shape" in str(o["data"].get("text/plain", ""))]
    assert kept, "the studio's picture, kept when the notebook is saved"
    widgets = [o for o in outputs if "application/vnd.jupyter.widget-view+json" in o.get("data", {})]
    assert widgets, "the studio was shown inline as a widget (through the kernel, no port)"
    assert not any("127.0.0.1" in str(o.get("data", {})) for o in outputs), "no page served on a local port"
    assert "<arap.StudioWidget running" in text
