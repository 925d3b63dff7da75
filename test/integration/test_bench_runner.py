"""bench/run.py: table and JSON rows (docs/architecture.md, Benchmarks)."""
from __future__ import annotations

import importlib.util
import json
import sys

import pytest

from prisma_testing.repo_paths import ROOT

BENCH = ROOT / "bench" / "run.py"


@pytest.fixture()
def runner():
    spec = importlib.util.spec_from_file_location("bench_run", BENCH)
    module = importlib.util.module_from_spec(spec)
    sys.modules["bench_run"] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    yield module
    sys.modules.pop("bench_run", None)


def test_rows_carry_ratio_and_json_keys(runner, tmp_path, monkeypatch, capsys):
    fake = runner.Benchmark("fake_parse", lambda: 2500.0, "frames/s", 100.0)
    monkeypatch.setattr(runner, "discover", lambda: [fake])
    assert runner.main(["--json", str(tmp_path / "b.json")]) == 0
    out = capsys.readouterr().out
    assert "fake_parse" in out and "25.0" in out
    rows = json.loads((tmp_path / "b.json").read_text())
    assert rows == [{"name": "fake_parse", "value": 2500.0, "unit": "frames/s", "need": 100.0, "ratio": 25.0}]


def test_unknown_only_name_is_an_error(runner, monkeypatch):
    monkeypatch.setattr(runner, "discover", lambda: [])
    with pytest.raises(SystemExit):
        runner.main(["--only", "nope"])


def test_empty_registry_prints_header_only(runner, monkeypatch, capsys):
    monkeypatch.setattr(runner, "discover", lambda: [])
    assert runner.main([]) == 0
    assert capsys.readouterr().out.splitlines()[0].split()[:2] == ["name", "measured"]
