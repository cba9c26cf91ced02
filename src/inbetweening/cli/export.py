"""``python -m inbetweening.export``: export a checkpoint's network (the functions: :mod:`inbetweening.api.export`).

    python -m inbetweening.export ckpt_path=run/checkpoints/last.ckpt format=onnx output=model.onnx [opset=17]
"""
from __future__ import annotations

import sys
from collections.abc import Sequence

from inbetweening.cli.args import UsageError, fail, parse_args, parse_bool

FORMATS = ("onnx", "ckpt")

USAGE = """\
usage: python -m inbetweening.export ckpt_path=<model.ckpt> format=onnx|ckpt output=<file> [opset=17] [check=true]

Export the network of a training checkpoint.  Options may be given as key=value or --key value.

  ckpt_path=PATH   training checkpoint (.ckpt)                                       (required)
  format=onnx      ONNX graph of the network                                         (default onnx)
  format=ckpt      inference-only Lightning checkpoint: weights + hyper-parameters, no optimiser
                   state (loads with InbetweenModule.load_from_checkpoint / Inbetweener)
  output=PATH      file to write                                                     (required)
  opset=N          ONNX opset version                                                (default 17)
  check=BOOL       run the exported model with ONNX Runtime on a random window and
                   print the largest difference to PyTorch                           (default true)
  --force          allow output to be the input checkpoint itself (refused otherwise)

The ONNX graph computes net(x, known, interp) with dynamic batch and frame axes; the skeleton, the
normalisation statistics, the mask, the forward axis and n_past are stored as JSON in metadata_props.
"""


def run(argv: Sequence[str]) -> int:
    try:
        args = parse_args(argv, {"ckpt_path": str, "format": str, "output": str, "opset": int, "check": parse_bool,
                                 "force": parse_bool},
                          {"ckpt": "ckpt_path", "checkpoint": "ckpt_path", "out": "output", "o": "output"})
    except UsageError as e:
        fail(e)
    if args is None:
        print(USAGE)
        return 0
    missing = [k for k in ("ckpt_path", "output") if k not in args]
    if missing:
        fail(f"missing {', '.join(f'{k}=...' for k in missing)} (see --help)")
    fmt = str(args.get("format", "onnx")).lower()
    if fmt not in FORMATS:
        fail(f"format: unknown export format {args['format']!r}; supported: {', '.join(FORMATS)}")
    from inbetweening.api.export import ExportError, export_checkpoint, export_onnx
    from inbetweening.atomic import same_file
    from inbetweening.predictor.checkpoint import CheckpointError, load_predictor

    if same_file(args["ckpt_path"], args["output"]) and not args.get("force", False):
        fail(f"output: {args['output']} is the checkpoint being exported; writing it would destroy the input "
             "(choose another output, or --force to overwrite)")

    try:
        if fmt == "ckpt":
            info = export_checkpoint(args["ckpt_path"], args["output"])
            print(f"wrote {info['path']} ({info['bytes'] / 1e6:.2f} MB, weights and hyper-parameters only)")
            return 0
        predictor = load_predictor(args["ckpt_path"])
        info = export_onnx(predictor, args["output"], opset=args.get("opset", 17), check=args.get("check", True))
    except (CheckpointError, ExportError, OSError) as e:
        fail(e)
    print(f"wrote {info['path']} (inputs: {', '.join(info['inputs'])}; dynamic axes: batch, frames)")
    if info["max_abs_diff"] is not None:
        print(f"onnxruntime vs PyTorch on a random window: max abs diff {info['max_abs_diff']:.3g}")
    return 0


def main() -> None:
    sys.exit(run(sys.argv[1:]))


if __name__ == "__main__":
    main()
