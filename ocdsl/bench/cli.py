"""``ocdsl bench FILES...``: each problem file through ``ocdsl run`` and a generated CasADi script.

Imports only click at module level, so registering the command keeps ``ocdsl --help`` fast.
"""
from __future__ import annotations

from pathlib import Path

import click


@click.command()
@click.argument("files", nargs=-1, required=True, type=click.Path(dir_okay=False, exists=True))
@click.option("--runs", type=int, default=3, show_default=True, help="runs of each tool per file (medians)")
@click.option("--out", type=click.Path(dir_okay=False), default="reports/bench/peers.md", show_default=True)
@click.option("--scaling", "scaling_file", type=click.Path(dir_okay=False, exists=True), default=None,
              help="problem file of the build-time scaling series")
@click.option("--scaling-segments", default="10,20,50,100,200,500,1000,2000,5000", show_default=True)
@click.option("--scaling-repeat", type=int, default=3, show_default=True,
              help="builds per segment count in the scaling series (CPU medians)")
@click.option("--series-solve", default="", help="segment counts at which the scaling problem is also solved")
def bench(files, runs, out, scaling_file, scaling_segments, scaling_repeat, series_solve):
    """Compare ocdsl with a CasADi script generated from the same problem (CasADi is a dependency: its Ipopt build is ocdsl's)."""
    try:
        seg = [int(k) for k in scaling_segments.split(",") if k.strip()]
        solve = [int(k) for k in series_solve.split(",") if k.strip()]
    except ValueError as e:
        raise click.UsageError(f"--scaling-segments / --series-solve take integers separated by commas: {e}") from None
    if solve and scaling_file is None:
        raise click.UsageError("--series-solve needs --scaling FILE (the problem of the scaling series)")
    _refuse_foreign(Path(out))
    try:
        import casadi  # noqa: F401
    except ImportError:
        raise click.ClickException("the CasADi comparison needs CasADi: make setup installs it (a dependency of ocdsl)") from None
    from .peers import main_peers

    click.echo(main_peers([Path(f) for f in files], runs, Path(out), Path(scaling_file) if scaling_file else None,
                          seg, solve, scaling_repeat))


HEADING = "# ocdsl against a generated CasADi script"     # the first line of what bench writes


class _Refused(click.ClickException):
    exit_code = 2      # a usage error, as a refused `run --out`


def _refuse_foreign(out: Path) -> None:
    """Before any run: ``out`` is new or an earlier bench table (its first line), never a
    file of the user's (unseen12 F3: `--out notes.md` replaced it)."""
    if not out.exists():
        return
    try:
        with open(out, encoding="utf-8") as fh:
            first = fh.readline().rstrip("\n")
    except (OSError, UnicodeDecodeError):
        first = ""
    if not out.is_file() or first != HEADING:
        raise _Refused(f"{out} exists and is not a table ocdsl bench wrote (its first line is not "
                       f"'{HEADING}'); nothing was run: choose another --out, or move it")
