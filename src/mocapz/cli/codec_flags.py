"""Command-line flags made from the codecs' option declarations, and help that lists them per codec.

Every declared option (:mod:`mocapz.codecs.options`) with ``cli=True`` becomes one flag on ``compress``
and ``compress-db``; values reach the codec as text and are checked by its declaration, so a flag means
the same in every codec that declares it. ``mocapz compress --codec NAME --help`` shows NAME's options;
plain ``--help`` lists the codecs and the common targets.
"""

from __future__ import annotations

from typing import Any

import click

from mocapz.codecs import CodecInfo, all_codecs, get_codec
from mocapz.codecs.options import Option
from mocapz.codecs.target import TARGET_NAMES
from mocapz.errors import MocapzError


def declared_flags() -> dict[str, Option]:
    """Every command-line option of every codec, by name (the first declaration of a name wins)."""
    out: dict[str, Option] = {}
    for info in all_codecs():
        for o in info.options:
            if o.cli:
                out.setdefault(o.name, o)
    return out


def codec_flags(codec_filter: str | None = None) -> Any:
    """Decorator adding the flags of every codec (or of one codec) to a click command, hidden from the
    generic option list (:class:`CodecCommand` prints them)."""
    def deco(f: Any) -> Any:
        options = declared_flags() if codec_filter is None else {
            o.name: o for o in get_codec(codec_filter).options if o.cli}
        for o in reversed(list(options.values())):
            if o.kind == "bool":
                f = click.option(f"{o.flag}/--no-{o.flag[2:]}", o.name, default=None, hidden=True)(f)
            else:
                f = click.option(o.flag, o.name, default=None, metavar=o.metavar, hidden=True)(f)
        return f
    return deco


def given(params: dict[str, Any]) -> dict[str, Any]:
    """The codec options given on the command line (flags left out are not passed)."""
    names = declared_flags()
    return {k: v for k, v in params.items() if k in names and v is not None}


def _rows(options: tuple[Option, ...]) -> list[tuple[str, str]]:
    rows = []
    for o in options:
        if not o.cli:
            continue
        flag = o.flag if o.kind != "bool" else f"{o.flag} / --no-{o.flag[2:]}"
        rows.append((f"{flag} {o.metavar}".strip(), f"{o.help} [{o.accepts()}; default: {o.describe_default()}]"))
    return rows


class CodecCommand(click.Command):
    """A command whose help shows the codec options: of the ``--codec`` given, else the codec list."""

    def parse_args(self, ctx: click.Context, args: list[str]) -> list[str]:
        for i, a in enumerate(args):
            if a == "--codec" and i + 1 < len(args):
                ctx.meta["mocapz.codec"] = args[i + 1]
            elif a.startswith("--codec="):
                ctx.meta["mocapz.codec"] = a.split("=", 1)[1]
        return super().parse_args(ctx, args)

    def format_options(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        super().format_options(ctx, formatter)
        name = ctx.meta.get("mocapz.codec")
        if name is not None:
            try:
                info = get_codec(name)
            except MocapzError as exc:
                raise click.UsageError(str(exc), ctx) from None
            with formatter.section(f"Options of the {info.name} codec ({info.summary})"):
                formatter.write_dl(_rows(info.options) or [("(none)", "this codec takes no options")])
            return
        with formatter.section("Codecs (--codec NAME, any case)"):
            formatter.write_dl([(c.name, c.summary) for c in all_codecs()])
        targets = tuple(o for o in declared_flags().values() if o.name in TARGET_NAMES)
        with formatter.section("Targets (every lossy codec)"):
            formatter.write_dl(_rows(targets))
        formatter.write_paragraph()
        formatter.write_text("Each codec's own options: mocapz compress --codec NAME --help, or docs/options.md.")


def check_codec_options(codec: str, params: dict[str, Any]) -> tuple[CodecInfo, dict[str, Any]]:
    """The codec and its checked options from a command's parameters (OptionError: exit code 2)."""
    info = get_codec(codec)
    return info, info.validate(given(params))
