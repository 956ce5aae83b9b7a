"""The ``mocapz`` command group and its entry point :func:`main`.

Exit codes: 0 success, 1 a file failed (one line on stderr naming it), 2 usage (a bad flag or option
value, checked before any input is read), 130 on Ctrl-C. No traceback is ever shown.
"""

from __future__ import annotations

import sys

import click

from mocapz import __version__
from mocapz.errors import MocapzError, OptionError

KERNELS = {"ahead of time": "compiled ahead of time",
           "numba": "numba's, compiled just in time (`make kernels` or `python -m mocapz.aot_build` compiles them "
                    "ahead of time: about 0.5 s and 100 MB less a command)",
           "none": "none: the NumPy paths (numba not installed, or MOCAPZ_NO_NUMBA)"}


def _print_version(ctx: click.Context, _param: click.Parameter, value: bool) -> None:
    """``-V``: the version and which compiled kernels the commands use (:func:`mocapz.aot.in_use`)."""
    if not value or ctx.resilient_parsing:
        return
    from mocapz import aot

    click.echo(f"mocapz, version {__version__}\nkernels: {KERNELS[aot.in_use()]}")
    ctx.exit()


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.option("-V", "--version", is_flag=True, expose_value=False, is_eager=True, callback=_print_version,
              help="Show the version and the compiled kernels in use, and exit.")
def cli() -> None:
    """Compress human motion-capture data (BVH, ASF/AMC, C3D, TRC).

    mocapz compress clip.bvh writes clip.bvh.mcz; mocapz decompress clip.bvh.mcz writes clip.bvh.
    """


def _register_commands() -> None:
    """Commands, one module each."""
    from mocapz.cli.bench import bench
    from mocapz.cli.compress import compress
    from mocapz.cli.db import compress_db, verify
    from mocapz.cli.decompress import decompress
    from mocapz.cli.inspect_cmds import eval_cmd, info
    from mocapz.cli.view import view

    for command in (compress, decompress, info, eval_cmd, view, bench, compress_db, verify):
        cli.add_command(command)


_register_commands()


def main(argv: list[str] | None = None) -> None:
    """Entry point: run the CLI, turning mocapz errors into one line on stderr and an exit code."""
    try:
        cli.main(args=argv, prog_name="mocapz", standalone_mode=False)
    except click.exceptions.Abort:
        click.echo("mocapz: interrupted", err=True)
        sys.exit(130)
    except click.UsageError as exc:
        exc.show()
        sys.exit(2)
    except click.ClickException as exc:
        exc.show()
        sys.exit(exc.exit_code)
    except OptionError as exc:
        click.echo(f"mocapz: error: {exc}", err=True)
        sys.exit(2)
    except MocapzError as exc:
        click.echo(f"mocapz: error: {exc}", err=True)
        sys.exit(1)
    except KeyboardInterrupt:
        click.echo("mocapz: interrupted", err=True)
        sys.exit(130)
    except BrokenPipeError:
        sys.exit(1)
    except MemoryError:
        click.echo("mocapz: error: out of memory", err=True)
        sys.exit(1)
    except Exception as exc:  # noqa: BLE001 - last resort: one line, never a traceback
        click.echo(f"mocapz: internal error: {type(exc).__name__}: {exc} (please report)", err=True)
        sys.exit(1)
    sys.exit(0)


if __name__ == "__main__":  # pragma: no cover
    main()
