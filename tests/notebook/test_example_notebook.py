"""The example notebook runs from top to bottom in a fresh kernel, the inline studio (a widget) included."""

from __future__ import annotations

from pathlib import Path

import nbformat
import pytest
from nbclient import NotebookClient

pytestmark = pytest.mark.timeout(240)

NOTEBOOK = Path(__file__).resolve().parents[2] / "docs" / "notebooks" / "first-deformation.ipynb"


def test_example_notebook_runs(tmp_path: Path) -> None:
    nb = nbformat.read(NOTEBOOK, as_version=4)
    NotebookClient(nb, timeout=180, kernel_name="python3", resources={"metadata": {"path": str(tmp_path)}}).execute()
    outputs = [o for cell in nb.cells if cell.cell_type == "code" for o in cell.outputs]
    assert not [o for o in outputs if o.output_type == "error"]
    text = "\n".join(str(o.get("text", "")) + str(o.get("data", {}).get("text/plain", "")) for o in outputs)
    assert "converged: True" in text
    assert "(True," in text  # the energies never rose
    plots = [o for o in outputs if "image/png" in o.get("data", {})]
    figures = [o for o in plots if str(o["data"].get("text/plain", "")).startswith("<Figure")]
    assert len(figures) == 1 and len(figures[0]["data"]["image/png"]) > 5_000  # the energy and shape figure was drawn
    pictures = [o for o in plots if "studio's shape" in str(o["data"].get("text/plain", ""))]
    assert pictures, "the studio's picture, kept when the notebook is saved"
    widgets = [o for o in outputs if "application/vnd.jupyter.widget-view+json" in o.get("data", {})]
    assert widgets, "the studio was shown inline as a widget (through the kernel, no port)"
    assert not any("127.0.0.1" in str(o.get("data", {})) for o in outputs), "no page served on a local port"
    assert "<arap.StudioWidget stopped" in text
