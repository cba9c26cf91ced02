"""``python -m inbetweening.blender``: build the Blender extension, or export a model for it."""
from __future__ import annotations

import sys
from collections.abc import Sequence

from inbetweening.cli.args import UsageError, fail, parse_args, parse_paths

USAGE = """\
usage: python -m inbetweening.blender build OUT_DIR [ckpt_path=<model.ckpt>|[a.ckpt,b.ckpt]]
                                         [platforms=linux-x64,windows-x64,macos-arm64] [onnxruntime=1.19.2]
                                         (platforms may also name macos-x64)
                                         [wheels=CACHE_DIR]
       python -m inbetweening.blender export ckpt_path=<model.ckpt> output=<model.onnx>

build   Write OUT_DIR/inbetweening-<version>-<platform>.zip for each platform: the Blender extension (Blender 4.2
        and later) with the checkpoint's model as ONNX + JSON metadata and the onnxruntime wheels.  A list of
        checkpoints (models of one skeleton) is bundled as their ensemble, which the extension fills with; default:
        [models/bn2_partial/model.ckpt,models/bn2_partial_twin/model.ckpt,
        models/bn2_v2/model.ckpt].  Wheels are downloaded from the package index
        once and cached (wheels=, or $INBETWEENING_WHEELS; default ~/.cache/inbetweening/blender-wheels).
export  Export a checkpoint (any skeleton) as the extension's model file: output.onnx and output.json; choose it
        in the extension's "Model" field.
"""


def _platforms(text: str) -> list[str]:
    return [p.strip() for p in text.split(",") if p.strip()]


def run(argv: Sequence[str]) -> int:
    argv = list(argv)
    if not argv or argv[0] in ("-h", "--help", "help"):
        print(USAGE)
        return 0 if argv else 2
    command, rest = argv[0], argv[1:]
    from inbetweening.blender.build import DEFAULT_CKPTS, DEFAULT_PLATFORMS, ONNXRUNTIME, BuildError, build, export

    try:
        if command == "build":
            positional = [a for a in rest if "=" not in a and not a.startswith("-")]
            if len(positional) != 1:
                raise UsageError("build needs exactly one OUT_DIR (see --help)")
            out_dir = positional[0]
            args = parse_args([a for a in rest if a != out_dir],
                              {"ckpt_path": parse_paths, "platforms": _platforms, "onnxruntime": str, "wheels": str},
                              {"ckpt": "ckpt_path", "checkpoint": "ckpt_path", "platform": "platforms"})
            if args is None:
                print(USAGE)
                return 0
            build(out_dir, args.get("ckpt_path", list(DEFAULT_CKPTS)), args.get("platforms", list(DEFAULT_PLATFORMS)),
                  args.get("onnxruntime", ONNXRUNTIME), args.get("wheels"))
            return 0
        if command == "export":
            args = parse_args(rest, {"ckpt_path": parse_paths, "output": str}, {"ckpt": "ckpt_path", "out": "output"})
            if args is None:
                print(USAGE)
                return 0
            missing = [k for k in ("ckpt_path", "output") if k not in args]
            if missing:
                raise UsageError(f"missing {', '.join(f'{k}=...' for k in missing)} (see --help)")
            if isinstance(args["ckpt_path"], list):
                raise UsageError("export takes one checkpoint (ckpt_path=<model.ckpt>); build bundles a list of them")
            meta = export(args["ckpt_path"], args["output"])
            print(f"wrote {args['output']} ({len(meta['skeleton_names'])} joints, n_past {meta['n_past']}, "
                  f"trained gap {meta['trained_gap']}; onnxruntime vs PyTorch {meta['onnxruntime_vs_pytorch_max_abs_diff']:.2g})")
            return 0
        raise UsageError(f"unknown command {command!r}; use build or export (see --help)")
    except (UsageError, BuildError) as e:
        fail(e)
    return 0


def main() -> None:
    sys.exit(run(sys.argv[1:]))


if __name__ == "__main__":
    main()
