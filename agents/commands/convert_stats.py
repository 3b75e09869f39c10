"""``python -m agents.model_files --trust-pickle OLD.pkl NEW.json``: legacy pickled statistics
(your own files only) to JSON."""

from __future__ import annotations

from pathlib import Path

from agents.artifacts.files import writable_problem
from agents.artifacts.stats import convert_pickled_stats


def main(argv: list[str] | None = None) -> int:
    """``python -m agents.model_files --trust-pickle OLD.pkl NEW.json``: convert statistics."""
    import argparse

    parser = argparse.ArgumentParser(
        prog="python -m agents.model_files",
        description="Convert pickled VecNormalize statistics (your own files) to JSON.",
    )
    parser.add_argument("pickled", type=Path, help="the *_vecnormalize.pkl to convert")
    parser.add_argument("destination", type=Path, help="the .json to write")
    parser.add_argument(
        "--trust-pickle", action="store_true", help="required: the conversion unpickles the file"
    )
    parser.add_argument("--overwrite", action="store_true", help="replace the destination")
    args = parser.parse_args(argv)
    if not args.trust_pickle:
        parser.error("argument --trust-pickle: required, the conversion unpickles the file")
    if not args.pickled.is_file():
        parser.error(f"argument pickled: no file {args.pickled}")
    problem = writable_problem(args.destination)
    if problem is not None:
        parser.error(f"argument destination: {problem}")
    try:
        print(f"wrote {convert_pickled_stats(args.pickled, args.destination, args.overwrite)}")
    except (FileExistsError, ValueError) as error:
        parser.error(f"argument destination: {error}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
