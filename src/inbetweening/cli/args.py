"""Tiny ``key=value`` / ``--key value`` argument parsing shared by the ``python -m inbetweening.*`` tools.

Hydra-style ``key=value`` tokens and argparse-style ``--key value`` / ``--key=value`` are both accepted;
``-`` and ``_`` are interchangeable in keys; ``--no-<key>`` sets a boolean option to false.
"""
from __future__ import annotations

import sys
from collections.abc import Callable, Sequence


class UsageError(ValueError):
    """A bad command line; printed as one ``error: ...`` line with exit status 2."""


def parse_bool(text: str) -> bool:
    v = text.strip().lower()
    if v in ("1", "true", "yes", "on"):
        return True
    if v in ("0", "false", "no", "off"):
        return False
    raise ValueError(f"expected true or false, got {text!r}")


def parse_int_list(text: str) -> list[int]:
    """``"[0,30,75]"``, ``"0,30,75"`` or ``"0 30 75"`` -> ``[0, 30, 75]``."""
    body = text.strip()
    if body.startswith("[") and body.endswith("]"):
        body = body[1:-1]
    parts = [p for p in body.replace(",", " ").split() if p]
    out = []
    for p in parts:
        try:
            out.append(int(p))
        except ValueError:
            raise ValueError(f"{p!r} is not an integer") from None
    return out


def parse_paths(text: str) -> str | list[str]:
    """``"a.ckpt"`` -> ``"a.ckpt"``; ``"[a.ckpt,b.ckpt]"`` or ``"a.ckpt,b.ckpt"`` -> ``["a.ckpt", "b.ckpt"]``."""
    body = text.strip()
    if body.startswith("[") and body.endswith("]"):
        body = body[1:-1]
    parts = [p.strip() for p in body.split(",") if p.strip()]
    if not parts:
        raise ValueError("no path given")
    return parts[0] if len(parts) == 1 else parts


def parse_partial_keys(text: str) -> dict[int, list[str]]:
    """``"45:UpperArm_L,LowerArm_L,Hand_L;60:UpperLeg_R"`` -> ``{45: ["UpperArm_L", "LowerArm_L", "Hand_L"], 60:
    ["UpperLeg_R"]}``: partial keys, a frame and the bones keyed there, ``;`` between frames."""
    out: dict[int, list[str]] = {}
    for item in (p.strip() for p in text.split(";")):
        if not item:
            continue
        frame, sep, bones = item.partition(":")
        names = [b.strip() for b in bones.split(",") if b.strip()]
        if not sep or not names:
            raise ValueError(f"{item!r} is not FRAME:BONE,BONE,... (e.g. 45:UpperArm_L,LowerArm_L)")
        try:
            t = int(frame)
        except ValueError:
            raise ValueError(f"{frame.strip()!r} is not an integer frame") from None
        if t in out:
            raise ValueError(f"frame {t} is given twice")
        out[t] = names
    return out


def parse_args(argv: Sequence[str], options: dict[str, Callable[[str], object]],
               aliases: dict[str, str] | None = None) -> dict[str, object] | None:
    """Parse ``argv`` into ``{key: converted value}``; ``None`` when help was asked for.

    ``options`` maps each key to its converter (``str``, ``int``, :func:`parse_bool`, ...); keys given with
    :func:`parse_bool` may also be passed as a bare ``--key`` (true) or ``--no-key`` (false).
    Raises :class:`UsageError` for unknown keys, missing values and values the converter rejects.
    """
    aliases = aliases or {}
    out: dict[str, object] = {}
    args = list(argv)
    i = 0

    def key_of(raw: str) -> str:
        k = raw.replace("-", "_")
        k = aliases.get(k, k)
        if k not in options:
            raise UsageError(f"unknown option {raw!r}; known: {', '.join(sorted(options))} (see --help)")
        return k

    while i < len(args):
        tok = args[i]
        i += 1
        if tok in ("-h", "--help", "help"):
            return None
        if tok.startswith("--"):
            body = tok[2:]
            if "=" in body:
                raw, value = body.split("=", 1)
            elif body.startswith(("no-", "no_")):
                k = key_of(body[3:])
                if options[k] is not parse_bool:
                    raise UsageError(f"--{body} is only valid for true/false options")
                out[k] = False
                continue
            else:
                raw = body
                k = key_of(raw)
                nxt = args[i] if i < len(args) else None
                if options[k] is parse_bool and (nxt is None or nxt.startswith("-") or "=" in nxt):
                    out[k] = True
                    continue
                if nxt is None:
                    raise UsageError(f"--{raw} needs a value")
                value = nxt
                i += 1
        elif "=" in tok:
            raw, value = tok.split("=", 1)
        else:
            raise UsageError(f"unexpected argument {tok!r}: use key=value or --key value (see --help)")
        k = key_of(raw)
        try:
            out[k] = options[k](value)
        except ValueError as e:
            raise UsageError(f"{k}: {e}") from None
    return out


def fail(message: str) -> None:
    """Print ``error: <message>`` (one line) on stderr and exit with status 2."""
    print(f"error: {' '.join(str(message).split())}", file=sys.stderr)
    raise SystemExit(2)
