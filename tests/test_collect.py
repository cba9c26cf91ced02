"""``inbetweening.collect``: the split a run recorded is shown; older benchmark.json files keep working."""
from __future__ import annotations

import json
from pathlib import Path

from inbetweening.evaluation.collect import by_contents, collect, main, to_markdown


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


def _fold_run(root: Path, name: str, fold: int, seed: int, lever: str | None, model_cm: float, frames: int,
              worse: float = 0.0) -> None:
    run = root / name
    (run / ".hydra").mkdir(parents=True)
    over = ["experiment=folds", f"data.split=fold-{fold}", f"seed={seed}"] + ([lever] if lever else [])
    (run / ".hydra" / "overrides.yaml").write_text("\n".join(f"- {o}" for o in over) + "\n")
    (run / ".hydra" / "config.yaml").write_text(f"seed: {seed}\n")
    kf = {k: {"model_cm": model_cm, "interp_cm": 2.0, "n_frames": frames, "n_clips": 10, "worse_share": worse,
              "skate_model": 4.0, "skate_interp": 8.0, "skate_gt": 2.0} for k in ("15", "30")}
    res = {"dataset": "bandai_namco", "split": f"fold-{fold}", "model": "graph_transformer", "n_windows": 8,
           "metrics": {"l2p@15": 1.0}, "keyframes": kf}
    (run / "benchmark.json").write_text(json.dumps(res))


def test_folds_pool_every_clips_frames_and_spread_over_seeds(tmp_path):
    from inbetweening.evaluation.collect import by_folds

    # the baseline: fold 1 (100 frames at 1.0 cm) and fold 2 (300 frames at 2.0 cm) against 2.0 cm interpolation
    _fold_run(tmp_path, "base/0", 1, 1, None, 1.0, 100, worse=0.1)
    _fold_run(tmp_path, "base/1", 2, 1, None, 2.0, 300, worse=0.3)
    # a lever, two seeds
    for seed, cm in ((1, 1.0), (2, 1.6)):
        _fold_run(tmp_path, f"mirror_{seed}/0", 1, seed, "data.mirror=true", cm, 100)
        _fold_run(tmp_path, f"mirror_{seed}/1", 2, seed, "data.mirror=true", cm, 100)
    rows = by_folds(tmp_path)
    base = [r for r in rows if r["config"] == "(shared settings)"]
    assert [r["fold"] for r in base] == ["fold-1", "fold-2", "pooled"]
    assert abs(base[0]["15"] - 0.5) < 1e-12 and abs(base[1]["15"] - 1.0) < 1e-12
    assert abs(base[2]["15"] - (100 * 1.0 + 300 * 2.0) / (400 * 2.0)) < 1e-12  # frames, not folds, weigh
    assert abs(base[2]["worse@30"] - 0.2) < 1e-12 and abs(base[2]["skate@15"] - 2.0) < 1e-12
    lever = [r for r in rows if r["config"] == "data.mirror=true"][-1]
    assert lever["seeds"] == 2 and abs(lever["30"] - 0.65) < 1e-12 and abs(lever["30_std"] - 0.3 / 2 ** 0.5) < 1e-12
    assert main([str(tmp_path), "--folds"]) == 0
    md = (tmp_path / "folds.md").read_text()
    assert "| data.mirror=true | **pooled** (2 seeds) | – | 0.650 ± 0.212 (0.0 %) |" in md


def test_folds_without_fold_runs_is_one_line(tmp_path, capsys):
    _run(tmp_path, "a", 2.0, "content")
    assert main([str(tmp_path), "--folds"]) == 2
    assert capsys.readouterr().err.startswith("error: no benchmark.json of a fold")


def test_the_network_alone_is_a_column_beside_the_blended_fill(tmp_path):
    res = {"dataset": "bandai_namco", "model": "graph_transformer", "n_windows": 8, "metrics": {"l2p@15": 2.0},
           "interpolation": {"l2p@15": 4.0}, "network": {"l2p@15": 3.0}}
    (tmp_path / "a").mkdir()
    (tmp_path / "a" / "benchmark.json").write_text(json.dumps(res))
    row = collect(tmp_path)[0]
    assert row["l2p_ratio@15"] == 0.5 and row["net_l2p@15"] == 3.0 and row["net_l2p_ratio@15"] == 0.75
    assert to_markdown([row]).splitlines()[0] == "| config | model | L2P@15 | L2P_RATIO@15 | NET_L2P@15 | NET_L2P_RATIO@15 |"


def test_contents_split_a_pooled_result_by_the_clips_motion(tmp_path, capsys):
    """Per content: the median of its clips' ratios and the share worse than interpolation by more than 5 %, read from
    the clip names (a Bandai-Namco name's content, anything else under "(other)")."""
    ratios = {"dataset-2_run_active_001": 0.7, "dataset-2_run_elderly_002": 0.9, "dataset-2_run_active_003": 1.2,
              "dataset-2_wave-both-hands_normal_001": 1.1, "dataset-2_wave-both-hands_normal_002": 1.0,
              "my_take": 0.5}
    res = {"keyframes": {"15": {"ratio": 0.9, "clip_ratios": ratios},
                         "30": {"ratio": 0.8, "clip_ratios": {k: v / 2 for k, v in ratios.items()}}}}
    (tmp_path / "a").mkdir()
    (tmp_path / "a" / "benchmark.json").write_text(json.dumps(res))
    (tmp_path / "lafan.json").write_text(json.dumps({"metrics": {"l2p@15": 1.0}}))  # no clips: not a row
    rows = {r["content"]: r for r in by_contents(tmp_path)}
    assert set(rows) == {"run", "wave-both-hands", "(other)"}
    assert rows["run"]["clips"] == 3 and rows["run"]["15"] == 0.9 and abs(rows["run"]["worse@15"] - 1 / 3) < 1e-12
    assert rows["wave-both-hands"]["15"] == 1.05 and rows["wave-both-hands"]["worse@15"] == 0.5
    assert rows["run"]["30"] == 0.45 and rows["run"]["worse@30"] == 0.0
    assert rows["(other)"]["15"] == 0.5
    assert main([str(tmp_path), "--contents"]) == 0
    assert "| a | run | 3 | 0.900 (33.3 %) | 0.450 (0.0 %) |" in capsys.readouterr().out
    assert main([str(tmp_path / "a" / "benchmark.json"), "--contents"]) == 0  # one file: the table beside it
    assert "| a | run | 3 |" in (tmp_path / "a" / "contents.md").read_text() and (tmp_path / "a" / "contents.csv").exists()
    assert main([str(tmp_path / "lafan.json"), "--contents"]) == 2
    assert "no keys-only benchmark with per-clip ratios" in capsys.readouterr().err
