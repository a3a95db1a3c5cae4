"""Files the commands read and write, checked at the boundary: inputs must be regular files of a
bounded size, outputs are written whole or not at all, and output paths are checked before any work
starts.

Why one module: a full disk left a truncated CSV beside a normal sidecar (which ``localize`` then
accepted), a FIFO or ``/dev/zero`` as an input blocked forever, and an unwritable output failed with
a traceback after minutes of work.  Every command reads and writes through these few functions, so
the promise (one line, exit 2, nothing half-written) has one home.
"""

from __future__ import annotations

import contextlib
import errno
import os
import stat
import tempfile
from collections.abc import Iterator
from pathlib import Path

from mission.errors import InputError

MAX_TEXT_BYTES = (
    200_000_000  # a flight log of a few hours at 50 Hz is ~100 MB; more is not an input we read
)


def _why(e: OSError) -> str:
    """The OS's reason in words ('No space left on device', 'File too large')."""
    return e.strerror or (errno.errorcode.get(e.errno or 0) or str(e))


def check_regular(
    path: str | Path, what: str = "file", field: str | None = None, max_bytes: int | None = None
) -> Path:
    """``path`` if it is an existing regular file (not a folder, FIFO or device) of at most
    ``max_bytes``; else an InputError naming it.  A FIFO with no writer or ``/dev/zero`` would block
    or never end."""
    p = Path(path)
    try:
        st = p.stat()
    except FileNotFoundError:
        raise InputError(f"no such {what}", source=str(p), field=field) from None
    except OSError as e:
        raise InputError(f"cannot read the {what}: {_why(e)}", source=str(p), field=field) from None
    if stat.S_ISDIR(st.st_mode):
        raise InputError(f"is a directory, not a {what}", source=str(p), field=field)
    if not stat.S_ISREG(st.st_mode):
        raise InputError(
            f"is not a regular file (a pipe or a device?); give a {what}",
            source=str(p),
            field=field,
        )
    if max_bytes is not None and st.st_size > max_bytes:
        raise InputError(
            f"is {st.st_size / 1e6:.1f} MB; a {what} may be at most {max_bytes / 1e6:g} MB",
            source=str(p),
            field=field,
        )
    return p


def read_bytes(
    path: str | Path, what: str = "file", field: str | None = None, max_bytes: int = MAX_TEXT_BYTES
) -> bytes:
    """The bytes of a regular input file (``check_regular``), read errors as one-line
    InputErrors."""
    p = check_regular(path, what, field, max_bytes)
    try:
        return p.read_bytes()
    except OSError as e:
        raise InputError(f"cannot read the {what}: {_why(e)}", source=str(p), field=field) from None


def read_text(
    path: str | Path,
    what: str = "file",
    field: str | None = None,
    max_bytes: int = MAX_TEXT_BYTES,
    encoding: str = "utf-8",
) -> str:
    """The text of a regular input file; bytes that are not ``encoding`` are an InputError (a binary
    or Latin-1 file given where a YAML or JSON file belongs)."""
    data = read_bytes(path, what, field, max_bytes)
    try:
        return data.decode(encoding)
    except UnicodeDecodeError as e:
        raise InputError(
            f"is not a UTF-8 text {what} (byte {e.start} is 0x{data[e.start]:02x}); binary?",
            source=str(path),
            field=field,
        ) from None


@contextlib.contextmanager
def writing(path: str | Path, field: str | None = None) -> Iterator[Path]:
    """Yield a temporary path in ``path``'s folder; when the block ends, move it onto ``path`` at
    once (``os.replace``).  A failure (full disk, file-size limit, Ctrl-C) removes the temporary
    file and leaves whatever ``path`` held before: the file is written whole or not at all.  OS
    errors become an InputError naming ``path``."""
    p = Path(path)
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp_name = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".part", dir=p.parent)
        os.close(fd)
    except OSError as e:
        raise InputError(f"cannot write: {_why(e)}", source=str(p), field=field) from None
    tmp = Path(tmp_name)
    try:
        yield tmp
        with open(tmp, "rb+") as f:  # the data is on disk before the name points at it
            os.fsync(f.fileno())
        os.chmod(tmp, 0o644 & ~_umask())
        os.replace(tmp, p)
    except OSError as e:
        tmp.unlink(missing_ok=True)
        raise InputError(
            f"cannot write: {_why(e)} (nothing written)", source=str(p), field=field
        ) from None
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_text(path: str | Path, text: str, field: str | None = None) -> Path:
    """Write ``text`` to ``path`` whole or not at all (``writing``)."""
    with writing(path, field) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)


def write_bytes(path: str | Path, data: bytes, field: str | None = None) -> Path:
    """Write ``data`` to ``path`` whole or not at all (``writing``)."""
    with writing(path, field) as tmp:
        tmp.write_bytes(data)
    return Path(path)


def save_figure(fig, path: str | Path, field: str | None = None, **kw) -> Path:
    """``fig.savefig`` whole or not at all (the format from ``path``'s suffix, not the temporary
    name's)."""
    p = Path(path)
    with writing(p, field) as tmp:
        fig.savefig(tmp, format=p.suffix.lstrip(".").lower() or "png", **kw)
    return p


def _nearest_existing(path: Path) -> Path:
    for p in (path, *path.parents):
        if p.exists():
            return p
    return Path(".")


def check_writable_dir(folder: str | Path, field: str | None = "--out") -> Path:
    """``folder`` if it is, or can be made, a writable folder (nothing is created); else an
    InputError.

    Why a probe and not ``os.access``: as root ``os.access`` says yes to a read-only mount or
    ``/proc``; an anonymous temporary file in the nearest existing folder is the honest test and
    leaves nothing behind."""
    folder = Path(folder)
    for p in (folder, *folder.parents):
        if p.exists() and not p.is_dir():
            raise InputError(f"{p} is a file, not a folder", source=str(folder), field=field)
    base = _nearest_existing(folder)
    try:
        with tempfile.TemporaryFile(dir=base):
            pass
    except OSError as e:
        raise InputError(
            f"cannot write in {base}: {_why(e)}", source=str(folder), field=field
        ) from None
    return folder


def check_out_file(
    path: str | Path,
    field: str | None = "--out",
    overwrite: bool = False,
    hint: str = "use --overwrite to replace it",
) -> Path:
    """An output file's path checked before any work: not a folder, its folder writable (or
    creatable), and not an existing file unless ``overwrite``."""
    p = Path(path)
    if p.is_dir():
        raise InputError("is a directory; give a file name", source=str(p), field=field)
    if p.exists() and not overwrite:
        raise InputError(f"exists already ({hint})", source=str(p), field=field)
    check_writable_dir(p.parent, field)
    return p
