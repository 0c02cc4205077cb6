"""What every user error must look like: exit code 2 and one line on stderr."""

from __future__ import annotations

from sigmarl.cli import main


def one_line_exit_2(args: list[str], capsys) -> str:
    """Run `sigmarl <args>`; assert rc 2 and a single 'sigmarl: error: ...' line; return it."""
    assert main(args) == 2
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("sigmarl: error: "), err
    return lines[0]
