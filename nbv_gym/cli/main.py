"""The ``nbv-gym`` command line: the app, its error boundary and its commands, each command in a
module of its own beside this one (heavy imports inside each command)."""

from __future__ import annotations

import importlib
from typing import Annotated, NoReturn

import typer

from nbv_gym.core.errors import NbvGymError
from nbv_gym.core.outputs import describe_os_error
from nbv_gym.core.progress import kernel_cache_error, speak_on_stderr


class _App(typer.Typer):
    """The CLI's one error boundary: nbv-gym's errors, bad options (Click's usage errors) and
    unusable files or folders (``OSError``: a full disk, no permission, a file where a folder
    should be) and an unreadable numba kernel cache become a one-line message and exit code 2;
    Ctrl-C a message and exit code 130."""

    def __call__(self, *args, **kwargs):
        try:
            code = super().__call__(*args, **{**kwargs, "standalone_mode": False})
        except NbvGymError as error:
            _fail(str(error), getattr(error, "exit_code", 2))
        except typer.Abort:
            _fail("aborted.", 1)
        except typer.TyperException as error:  # a bad option or argument (Click's usage errors)
            if type(error).__name__ == "NoArgsIsHelpError":  # `nbv-gym`, `nbv-gym worlds`: help
                typer.echo(error.format_message(), err=True)  # its message is the help
                raise SystemExit(error.exit_code) from None
            _fail(_usage_message(error), getattr(error, "exit_code", 2) or 2)
        except OSError as error:
            _fail(describe_os_error(error))
        except Exception as error:  # numba's own cache unreadable: say what to delete
            message = kernel_cache_error(error)
            if message is None:
                raise
            _fail(message)
        if code == 130:  # Click's answer to KeyboardInterrupt
            _fail("interrupted (Ctrl-C); what was finished is kept.", 130)
        raise SystemExit(code if isinstance(code, int) else 0)


def _fail(message: str, code: int = 2) -> NoReturn:
    typer.secho(f"Error: {' '.join(message.split())}", fg="red", err=True)
    raise SystemExit(code) from None


def _usage_message(error: Exception) -> str:
    """``nbv-gym view: Invalid value for '--max-points': expected …`` (Pydantic's "Value
    error, " prefix of a parser's message dropped)."""
    context = getattr(error, "ctx", None)
    where = f"{context.command_path}: " if context is not None else ""
    message = getattr(error, "format_message", lambda: str(error))()
    return where + message.replace("Value error, ", "")


app = _App(
    name="nbv-gym",
    help="A benchmark for autonomous lidar exploration and Next-Best-View research.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,
    # every command and group inherits these from the root context
    context_settings={"help_option_names": ["-h", "--help"]},
)


def _print_version(value: bool) -> None:
    if value:
        from importlib.metadata import version

        typer.echo(f"nbv-gym {version('nbv-gym')}")
        raise typer.Exit()


@app.callback()
def _options(
    version: Annotated[
        bool,
        typer.Option(
            "--version", callback=_print_version, is_eager=True, help="Print the version and exit."
        ),
    ] = False,
) -> None:
    pass


#: The commands, in the order ``--help`` lists them (Typer lists the groups after the commands):
#: (module of nbv_gym.cli, the function or Typer group, the command's name; None: the function's
#: name).
_COMMANDS = (
    ("run", "run", None),
    ("bench", "bench", None),
    ("evaluate", "evaluate", None),
    ("sweep", "sweep", None),
    ("sweep", "report", None),
    ("score", "score", None),
    ("score", "leaderboard", None),
    ("train", "train", None),
    ("package", "package_model", "package-model"),
    ("worlds", "worlds_app", "worlds"),
    ("study", "study_app", "study"),
    ("configs", "configs_app", "configs"),
    ("exports", "export", None),
    ("exports", "view", None),
    ("exports", "record", None),
)


def _register(commands: tuple[tuple[str, str, str | None], ...]) -> None:
    """Add ``commands`` (:data:`_COMMANDS`) to the app: functions as commands, Typer apps as
    groups."""
    for module, attribute, name in commands:
        target = getattr(importlib.import_module(f"nbv_gym.cli.{module}"), attribute)
        if isinstance(target, typer.Typer):
            app.add_typer(target, name=name)
        else:
            app.command(name)(target)


_register(_COMMANDS)


def main() -> None:
    """Entry point of the ``nbv-gym`` console script."""
    speak_on_stderr()
    app()
