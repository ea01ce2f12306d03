"""The one error type the command-line tools turn into exit code 2."""


class InputError(Exception):
    """Bad usage or bad input: the message names the file, the key or value, and what is allowed."""


def fail(e: InputError, debug: bool):
    """Print the one-paragraph message and exit 2 (or re-raise with a traceback under --debug)."""
    import click

    if debug:
        raise e
    click.echo(f"error: {e}", err=True)
    raise SystemExit(2)
