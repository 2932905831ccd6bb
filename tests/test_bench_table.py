"""tools/bench_table.py makes the results table of docs/benchmarks.md from the JSON files the benchmarks write."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from tests.tool_modules import load_benchmark, load_tool

bench_table = load_tool("bench_table")

MACHINE = {"cpu_count": 8, "python": "3.11.7", "platform": "Linux", "date": "2026-11-27T02:30:00+00:00"}


def _results(folder: Path, benchmark: str, figures: list[dict[str, Any]]) -> None:
    folder.mkdir(exist_ok=True)
    document = {"schema": 1, "benchmark": benchmark, "machine": MACHINE, "figures": figures, "data": {"raw": [1, 2]}}
    (folder / f"{benchmark}.json").write_text(json.dumps(document))


@pytest.fixture
def fixtures(tmp_path: Path) -> dict[str, Path]:
    results, modules = tmp_path / "results", tmp_path / "benchmarks"
    modules.mkdir()
    (modules / "bench_fast.py").write_text('"""Solving against a peer: the time of ``solve`` and\n'
                                           ':func:`arap.batch` on one mesh.\n\nRun: ``python bench_fast.py``\n"""\n')
    (modules / "bench_rate.py").write_text('"""Updates per second | of a session."""\n')
    _results(results, "bench_fast", [
        {"name": "time per iteration, bar", "value": 2.0, "unit": "ms", "peer": "libigl", "peer_value": 5.0,
         "better": "lower"},
        {"name": "precompute", "value": 1234.5, "unit": "ms", "better": "lower"},
        {"name": "distance", "value": 1e-15, "unit": "diagonals", "peer": "libigl", "peer_value": 0.1,
         "better": "lower"},
    ])
    _results(results, "bench_rate", [
        {"name": "updates per second", "value": 40.0, "unit": "updates/s", "peer": "target", "peer_value": 30.0,
         "better": "higher"},
    ])
    page = tmp_path / "benchmarks.md"
    page.write_text(f"# Benchmarks\n\nIntro.\n\n{bench_table.START}\nold table\n{bench_table.END}\n\nThe rest.\n")
    return {"results": results, "modules": modules, "page": page}


def _run(f: dict[str, Path], *extra: str) -> int:
    return int(bench_table.main(["--results", str(f["results"]), "--benchmarks", str(f["modules"]),
                                 "--out", str(f["page"]), *extra]))


def test_one_row_per_figure_with_peer_and_ratio(fixtures: dict[str, Path]) -> None:
    assert _run(fixtures) == 0
    page = fixtures["page"].read_text()
    rows = [line for line in page.splitlines() if line.startswith("| `bench_")]
    assert rows == [
        "| `bench_fast` | time per iteration, bar | 2 ms | libigl | 5 ms | 2.50× |",
        "| `bench_fast` | precompute | 1,234 ms | — | — | — |",
        "| `bench_fast` | distance | 1e-15 diagonals | libigl | 0.1 diagonals | ≥ 1,000× |",
        "| `bench_rate` | updates per second | 40 updates/s | target | 30 updates/s | 1.33× |",
    ]
    assert "| benchmark | figure | arap | peer | peer's | ratio |" in page


def test_the_paragraph_of_each_benchmark_comes_from_its_docstring(fixtures: dict[str, Path]) -> None:
    _run(fixtures)
    page = fixtures["page"].read_text()
    assert "### `bench_fast`\n\nSolving against a peer: the time of `solve` and `arap.batch` on one mesh.\n" in page
    assert "Run:" not in page  # the first paragraph only
    assert "Measured 2026-11-27 on 8 CPUs, Python 3.11.7" in page
    assert page.index("### `bench_fast`") < page.index("### `bench_rate`")


def test_only_the_generated_section_changes_and_a_second_run_is_stable(fixtures: dict[str, Path]) -> None:
    _run(fixtures)
    page = fixtures["page"].read_text()
    assert page.startswith("# Benchmarks\n\nIntro.\n\n" + bench_table.START)
    assert page.endswith(bench_table.END + "\n\nThe rest.\n")
    assert "old table" not in page
    assert page.count(bench_table.START) == 1 and page.count(bench_table.END) == 1
    assert _run(fixtures, "--check") == 0
    assert _run(fixtures) == 0 and fixtures["page"].read_text() == page


def test_check_reports_an_out_of_date_page(fixtures: dict[str, Path]) -> None:
    before = fixtures["page"].read_text()
    assert _run(fixtures, "--check") == 1
    assert fixtures["page"].read_text() == before


def test_a_page_without_markers_gets_the_section_after_its_title(fixtures: dict[str, Path]) -> None:
    fixtures["page"].write_text("# Benchmarks\n\nThe rest.\n")
    _run(fixtures)
    page = fixtures["page"].read_text()
    assert page.startswith("# Benchmarks\n\n" + bench_table.START)
    assert page.endswith(bench_table.END + "\n\nThe rest.\n")


def test_no_results_leave_a_note(fixtures: dict[str, Path], tmp_path: Path) -> None:
    fixtures["results"] = tmp_path / "empty"
    _run(fixtures)
    page = fixtures["page"].read_text()
    assert "No results yet" in page and "| benchmark |" not in page


def test_a_bad_results_file_is_refused(fixtures: dict[str, Path], capsys: pytest.CaptureFixture[str]) -> None:
    (fixtures["results"] / "bench_bad.json").write_text(json.dumps({"schema": 1, "benchmark": "bench_bad",
                                                                    "machine": MACHINE, "figures": [{"name": "x"}]}))
    before = fixtures["page"].read_text()
    assert _run(fixtures) == 2
    assert "bench_bad.json: figure 0 has no value, unit" in capsys.readouterr().err
    assert fixtures["page"].read_text() == before


def test_benchmarks_write_what_the_generator_reads(tmp_path: Path) -> None:
    """The writer the benchmarks share and the generator agree on the format."""
    benchjson = load_benchmark("benchjson")
    results = tmp_path / "results"
    benchjson.write_results(results / "bench_settle.json", "bench_settle",
                            [benchjson.figure("release to settled", 0.25, "s", "target", 0.5)], {"drags": [0.25]})
    page = tmp_path / "page.md"
    page.write_text("# Benchmarks\n")
    assert bench_table.main(["--results", str(results), "--out", str(page)]) == 0
    text = page.read_text()
    assert "| `bench_settle` | release to settled | 0.25 s | target | 0.5 s | 2.00× |" in text
    assert "time from releasing a drag" in text  # the real module's docstring
