"""The ``mocapz`` command group and its entry point :func:`main`.

Exit codes: 0 success, 1 a file failed (one line on stderr naming it), 2 usage (a bad flag or option
value, checked before any input is read), 130 on Ctrl-C. No traceback is ever shown.
"""

from __future__ import annotations

import sys

import click

from mocapz import __version__
from mocapz.errors import MocapzError, OptionError


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, "-V", "--version", prog_name="mocapz")
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
