"""The one error type the command-line tools turn into exit code 2, and the wrapper that gives every
way a command ends its exit code (README, "Exit codes"). Every message is printed as one
paragraph, whatever it quotes: a path may hold a newline, and a library's reason (gemmi's parse errors)
may run over several lines and quote control characters."""


class InputError(Exception):
    """Bad usage or bad input: the message names the file, the key or value, and what is allowed."""


def escaped(text: str) -> str:
    """`text` with every unprintable character escaped as Python writes it (\\n, \\x1b): a quoted path."""
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


def cut(text: str, limit: int = 200) -> str:
    """`text` as an error message quotes it (a library's reason, a value read from a file): escaped, at most
    `limit` characters, '...' where it was cut."""
    text = escaped(text)
    return text if len(text) <= limit else text[:limit] + "..."


def paragraph(text: str) -> str:
    """`text` on one line: its lines joined by spaces, every other unprintable character escaped."""
    return escaped(" ".join(line.strip() for line in text.splitlines() if line.strip()))


def fail(e: InputError, debug: bool):
    """Print the one-paragraph message (under --debug the traceback first) and exit 2."""
    import click

    if debug:
        import traceback

        traceback.print_exception(e)
    click.echo(f"error: {paragraph(str(e))}", err=True)
    raise SystemExit(2)


def guarded(work, debug: bool):
    """work()'s result, with the tools' exit codes: 2 for bad input (InputError) and for what the system
    refuses (OSError: a full disk, a read-only folder), 128 + N for SIGINT, SIGTERM and SIGHUP (after
    the staging folder is removed by the code that made it; vdmbake.signals)."""
    import click

    from . import signals

    signals.install()
    try:
        result = work()
        signals.check()
        return result
    except InputError as e:
        fail(e, debug)
    except (KeyboardInterrupt, signals.Interrupted) as e:
        click.echo(f"interrupted{f' ({e})' if str(e) else ''}; nothing was written", err=True)
        raise SystemExit(signals.exit_code(e)) from None
    except OSError as e:
        fail(InputError(f"{escaped(str(e.filename)) + ': ' if e.filename else ''}{e.strerror or e} "
                        f"({type(e).__name__}); nothing was written."), debug)
    except Exception as e:   # the signal's exception turned into another on its way up (an extension module's
        if signals.received is None:   # initialisation raises ImportError: "initialization failed")
            raise
        click.echo(f"interrupted ({type(e).__name__} where the signal arrived); nothing was written", err=True)
        raise SystemExit(signals.exit_code(e)) from None
