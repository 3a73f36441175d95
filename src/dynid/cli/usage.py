"""How each command presents itself in `--help`: what it is for, then one example (or a few).

Every sub-command is made with `command`, so that its help page has a description written for a user
and an `example:` block (RawDescriptionHelpFormatter keeps the example lines as written), and the
top-level `dynid --help` lists every command with its purpose and its first example (`overview`).
"""

from __future__ import annotations

import argparse
import textwrap
from collections.abc import Sequence

WIDTH = 78


def fill(text: str, indent: str = "") -> str:
    """Paragraphs (separated by blank lines) wrapped to the help's width."""
    return "\n\n".join(textwrap.fill(" ".join(p.split()), WIDTH, initial_indent=indent, subsequent_indent=indent)
                       for p in text.strip().split("\n\n"))


class UsageError(ValueError):
    """An option's value that parses but cannot be used (a negative --seed): one line naming the option and the
    fix, as every other bad input."""


def check_options(args: argparse.Namespace) -> None:
    """The options shared by several commands, checked before the command runs."""
    seed = getattr(args, "seed", None)
    if seed is not None and seed < 0:
        raise UsageError(f"--seed {seed}: give a whole number >= 0 (NumPy's generators take no negative seed; the "
                         "same seed gives the same noise)")


def command(subparsers: argparse._SubParsersAction, name: str, *, help: str, description: str,
            examples: str | Sequence[str], notes: str = "") -> argparse.ArgumentParser:
    """A sub-command whose help shows `description` (wrapped) and `examples` (kept as written, each a full
    command line, the first being the one `dynid --help` shows); `notes`: a paragraph after the examples."""
    examples = [examples] if isinstance(examples, str) else list(examples)
    epilog = "example" + ("s" if len(examples) > 1 else "") + ":\n" + "\n".join(f"  {e}" for e in examples)
    if notes:
        epilog += "\n\n" + fill(notes)
    p = subparsers.add_parser(name, help=help, description=fill(description), epilog=epilog,
                              formatter_class=argparse.RawDescriptionHelpFormatter)
    p.examples = examples  # type: ignore[attr-defined]  # read by `overview`
    return p


def overview(subparsers: argparse._SubParsersAction, order: Sequence[str] = ()) -> str:
    """The commands, each with its purpose and first example: the top-level help's epilog."""
    helps = {a.dest: a.help or "" for a in subparsers._choices_actions}
    names = [n for n in order if n in subparsers.choices] + [n for n in subparsers.choices if n not in order]
    width = max(len(n) for n in names) + 4
    lines = ["commands (dynid COMMAND --help shows a command's options and more examples):"]
    for n in names:
        lines.append(textwrap.fill(helps[n], WIDTH, initial_indent=f"  {n:<{width}}",
                                   subsequent_indent=" " * (width + 2)))
        first = getattr(subparsers.choices[n], "examples", [""])[0]
        lines.append(f"{'':{width + 2}}e.g. {first}")
    return "\n".join(lines)


__all__ = ["command", "fill", "overview"]
