"""``inbetweening.collect``: the split a run recorded is shown; older benchmark.json files keep working."""
from __future__ import annotations

import json
from pathlib import Path

from inbetweening.evaluation.collect import collect, main, to_markdown


def _run(root: Path, name: str, l2p: float, split: str | None = None) -> None:
    res = {"dataset": "bandai_namco", "model": "interpolation", "n_windows": 8, "metrics": {"l2p@15": l2p}}
    if split is not None:
        res["split"] = split
    (root / name).mkdir(parents=True)
    (root / name / "benchmark.json").write_text(json.dumps(res))


def test_collect_shows_the_split_when_recorded(tmp_path):
    _run(tmp_path, "a", 2.0, "content")
    _run(tmp_path, "b", 1.0)  # an older file: no split recorded
    rows = collect(tmp_path)
    assert [(r["run"], r["split"]) for r in rows] == [("b", None), ("a", "content")]
    md = to_markdown(rows).splitlines()
    assert md[0] == "| config | model | split | L2P@15 |" and md[1] == "|---|---|---|---:|"
    assert md[2] == "| b | interpolation |  | 1.000 |" and md[3] == "| a | interpolation | content | 2.000 |"
    assert main([str(tmp_path)]) == 0
    csv = (tmp_path / "results.csv").read_text().splitlines()
    assert csv[0] == "config,model,dataset,split,n_windows,l2p@15,run" and csv[2].split(",")[3] == "content"


def test_collect_of_files_without_a_split_is_unchanged(tmp_path):
    _run(tmp_path, "a", 2.0)
    md = to_markdown(collect(tmp_path)).splitlines()
    assert md[:2] == ["| config | model | L2P@15 |", "|---|---|---:|"]
    main([str(tmp_path)])
    assert (tmp_path / "results.csv").read_text().splitlines()[0] == "config,model,dataset,n_windows,l2p@15,run"
