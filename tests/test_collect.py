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


def _seed_run(root: Path, name: str, recipe: str, seed: int, l2p: float) -> None:
    res = {"dataset": "bandai_namco", "split": "standard", "model": "graph_transformer", "n_windows": 8,
           "metrics": {"l2p@15": l2p}, "interpolation": {"l2p@15": 4.0}}
    d = root / name
    (d / ".hydra").mkdir(parents=True)
    (d / ".hydra" / "overrides.yaml").write_text(f"- +recipe={recipe}\n- seed={seed}\n")
    (d / "benchmark.json").write_text(json.dumps(res))


def test_collect_ratios_to_interpolation_and_mean_over_seeds(tmp_path):
    _seed_run(tmp_path, "0", "base", 1, 3.0)
    _seed_run(tmp_path, "1", "base", 2, 2.0)
    _seed_run(tmp_path, "2", "last", 1, 1.0)
    rows = collect(tmp_path)
    assert [r["l2p_ratio@15"] for r in rows] == [0.25, 0.5, 0.75]
    assert main([str(tmp_path), "--seeds"]) == 0
    md = (tmp_path / "results.md").read_text().splitlines()
    assert md[0] == "| config | model | split | L2P@15 | L2P_RATIO@15 |"
    assert md[2] == "| +recipe=last | graph_transformer | standard | 1.000 ± 0.000 (1) | 0.250 ± 0.000 (1) |"
    assert md[3] == "| +recipe=base | graph_transformer | standard | 2.500 ± 0.707 (2) | 0.625 ± 0.177 (2) |"
    csv = (tmp_path / "results.csv").read_text().splitlines()
    assert csv[0] == "config,model,dataset,split,n_windows,n,l2p@15,l2p_ratio@15,l2p@15_std,l2p_ratio@15_std,run"
