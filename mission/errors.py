"""One exception type for bad user input, so every CLI can turn it into a one-line error and exit
code 2."""

from __future__ import annotations


class InputError(ValueError):
    """Bad input from a user (file, row, field or argument): reported as one line, exit code 2.

    The message should name where the problem is (file, row, column or key) and what was expected.
    """

    exit_code = 2

    def __init__(
        self,
        message: str,
        *,
        source: str | None = None,
        row: int | None = None,
        field: str | None = None,
    ) -> None:
        where = []
        if source:
            where.append(str(source))
        if row is not None:
            where.append(f"row {row}")
        if field:
            where.append(f"field '{field}'")
        prefix = ", ".join(where)
        super().__init__(one_line(f"{prefix}: {message}" if prefix else message))
        self.source, self.row, self.field = source, row, field


# Characters that end a line for ``str.splitlines`` (a terminal or a log reader): a user's key or
# value holding one (a YAML key with \x1d) must not split the one error line in two.
_LINE_BREAKS = {c: repr(c)[1:-1] for c in "\n\r\v\f\x1c\x1d\x1e\x85\u2028\u2029"}


def one_line(text: str) -> str:
    """``text`` with every line-breaking character written as its escape (``\\n``, ``\\x1d``)."""
    return (
        "".join(_LINE_BREAKS.get(c, c) for c in text)
        if any(c in _LINE_BREAKS for c in text)
        else text
    )
