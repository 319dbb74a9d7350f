"""Test helpers for the `ceco` verbs' command-line errors."""


def one_error_line(err: str) -> str:
    """The one line of a verb's stderr ``err`` but the progress line 'ceco report: loading ...'.

    Asserts there is no other line, no traceback and no trailing blank line (a user error is one line).
    """
    lines = [line for line in err.splitlines() if not line.startswith('ceco report: loading')]
    assert 'Traceback' not in err and len(lines) == 1 and not err.endswith('\n\n'), err
    return lines[0]
