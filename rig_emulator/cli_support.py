"""What both command-line tools share: one-line errors with exit code 2 for bad input."""

from __future__ import annotations

import argparse
import contextlib
import errno
import io
import math
import os
import re
import stat
import sys
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any

from rig_emulator.atomic import open_without_waiting
from rig_emulator.boilers import load_boiler
from rig_emulator.model.params import BoilerParams, ParameterError
from rig_emulator.names import host_name_problem


class UsageError(Exception):
    """Bad usage or input: reported as one line on stderr, exit code 2."""

    def __init__(self, message: str, prog: str | None = None) -> None:
        super().__init__(message)
        self.prog = prog


#: An argument that is a negative number to ``float``: argparse's own pattern (``-5``,
#: ``-.5``) missed ``-inf``, ``-nan`` and exponents (``-1e400``), which it took for an
#: unknown option (``--load -inf``: "expected one argument", not the range: a probe)
_NEGATIVE_NUMBER = re.compile(r"^-(?:\d|\.\d|inf|nan)", re.IGNORECASE)


class Parser(argparse.ArgumentParser):
    """An argument parser whose errors raise :class:`UsageError` instead of exiting, and
    that gives an option any argument that looks like a negative number (``--load -inf``,
    ``--room-temp -2e1``), so its ``type`` judges it (argparse treats such arguments as
    values where no option of the parser looks like a negative number: none does)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = _NEGATIVE_NUMBER

    def error(self, message: str) -> None:  # type: ignore[override]
        raise UsageError(message, self.prog)

    def _print_message(self, message: str, file: IO[str] | None = None) -> None:
        """As argparse's, but the write's error is raised (``--help`` into a full
        standard output exited 0 without a word: argparse drops it), a standard output the
        command was started without is one too (``--help >&-`` exited 0, its text lost or
        written to standard error: a probe), and a character the stream cannot carry is
        written readably (:func:`_write_readably`)."""
        if not message:
            return
        if file is None or (file is sys.stdout and stdout_missing()):  # argparse passes
            raise _closed_stdout()  # sys.stdout itself, None where it is missing
        _write_readably(file, message)


@contextmanager
def bad_input(*errors: type[Exception], prefix: str = "") -> Iterator[None]:
    """Turn ``errors`` raised in the block into a :class:`UsageError` ``PREFIX + message``."""
    try:
        yield
    except errors as exc:
        raise UsageError(f"{prefix}{exc}") from None


def boiler_arg(name: str) -> BoilerParams:
    """The boiler of a ``--boiler NAME|PATH`` option; a bad one is a :class:`UsageError`."""
    with bad_input(ParameterError):
        return load_boiler(name)


def _write_readably(stream: IO[str], text: str) -> int:
    """Write ``text`` to ``stream``, the characters its encoding cannot carry written
    readably (:func:`_readable_pieces`), whatever the stream's error handler. A file name
    with a byte that is no UTF-8 (``bad\\xff.csv``) under ``PYTHONIOENCODING=utf-8``
    ended ``hil-client run`` in a traceback and exit 1 after its log was written, and the
    rest of the line was lost (a stranger's probe)."""
    encoding = getattr(stream, "encoding", None)
    if not encoding or text.isascii():  # (a text stream in memory carries anything)
        return stream.write(text)
    try:
        text.encode(encoding)
    except UnicodeEncodeError:
        pass
    else:
        return stream.write(text)
    buffer = getattr(stream, "buffer", None)
    for piece in _readable_pieces(text, encoding, buffer is not None):
        if isinstance(piece, str):
            stream.write(piece)
        else:  # (after what the stream holds)
            stream.flush()
            buffer.write(piece)  # type: ignore[union-attr]
    if getattr(stream, "line_buffering", False) or getattr(stream, "write_through", False):
        stream.flush()
    return len(text)


def _readable_pieces(text: str, encoding: str, raw_bytes: bool) -> Iterator[str | bytes]:
    """``text`` in pieces ``encoding`` carries: a byte a file name held that was no text
    (decoded by ``surrogateescape``) as that byte (``raw_bytes``: the stream takes bytes)
    where the encoding carries a lone byte, else as ``\\xff``; any other character the
    encoding lacks as its backslash escape (``\\xe9`` for 'é' in ASCII). The text goes
    through the stream itself, which keeps its state (UTF-16's byte-order mark)."""
    lone_bytes = raw_bytes and _carries_lone_bytes(encoding)
    kept: list[str] = []
    for char in text:
        try:
            char.encode(encoding)
        except UnicodeEncodeError:
            pass
        else:
            kept.append(char)
            continue
        if not "\udc80" <= char <= "\udcff":
            kept.append(char.encode("ascii", "backslashreplace").decode("ascii"))
        elif lone_bytes:
            yield "".join(kept)
            kept.clear()
            yield bytes([ord(char) - 0xDC00])
        else:
            kept.append(f"\\x{ord(char) - 0xDC00:02x}")
    yield "".join(kept)


def _carries_lone_bytes(encoding: str) -> bool:
    """Whether a byte can stand alone among ``encoding``'s (not UTF-16 or -32)."""
    try:
        return "\udcff".encode(encoding, "surrogateescape") == b"\xff"
    except UnicodeEncodeError:
        return False


def stdout_missing() -> bool:
    """Whether the command was started without a standard output (``>&-``): Python then
    sets ``sys.stdout`` and ``sys.__stdout__`` to None, and the launcher
    (:func:`rig_emulator.launch.standard_streams`) points descriptor 1 at /dev/null for
    ``sys.stdout`` alone."""
    if sys.stdout is None:
        return True
    if sys.__stdout__ is not None:
        return False
    try:
        return sys.stdout.fileno() == 1
    except (OSError, ValueError):  # (io.UnsupportedOperation is both)
        return False


def _closed_stdout() -> OSError:
    """The error of output written to a standard output the command was started without,
    as ``cat >&-`` has it (Bad file descriptor)."""
    return OSError(errno.EBADF, os.strerror(errno.EBADF), "standard output")


class _GuardedStream:
    """A standard stream whose failures do not end the command's work.

    - A reader gone (a broken pipe: ``| head -1``) ends the messages, not the work: what
      follows is dropped and the command goes on (``hil-client run 2>&1 | head -1`` stopped
      acquiring at its next message, its meta saying nothing: a probe).
    - On standard error any failure does (there is nowhere left to say it).
    - On standard output another failure (a full disk) names it: it is no output file's
      fault (``balance --out x.json > /dev/full`` said "writing x.json: No space left on
      device" of a file written whole: a probe).
    - A standard output the command was started without (``missing``) takes what is
      written and drops it; :attr:`lost` says whether there was any, for the command to
      fail as it ends, its files written (``map-doc >&-`` exited 0, the reference
      written nowhere: a probe).
    - A character the stream's encoding cannot carry is written readably
      (:func:`_write_readably`).

    The descriptor of a stream given up on is pointed at /dev/null, so the interpreter's
    last flush at exit finds nothing to complain about."""

    def __init__(
        self,
        stream: IO[str] | None,
        name: str,
        fd: int,
        quiet_on_any: bool,
        missing: bool = False,
    ) -> None:
        self._stream: IO[str] = io.StringIO() if stream is None else stream
        self._name = name
        self._fd = fd
        self._quiet_on_any = quiet_on_any
        self._missing = missing
        self._gone = missing
        self.lost = False

    def _failed(self, exc: OSError) -> None:
        if self._quiet_on_any or exc.errno == errno.EPIPE:
            self._gone = True
            with contextlib.suppress(OSError):
                null = os.open(os.devnull, os.O_WRONLY)
                os.dup2(null, self._fd)
                os.close(null)
            return
        if exc.filename is None:
            exc.filename = self._name
        raise exc

    def write(self, text: str) -> int:
        if self._gone:
            self.lost = self.lost or (self._missing and bool(text))
            return len(text)
        try:
            return _write_readably(self._stream, text)
        except OSError as exc:
            self._failed(exc)
            return len(text)

    def flush(self) -> None:
        if self._gone:
            return
        try:
            self._stream.flush()
        except OSError as exc:
            self._failed(exc)

    def __getattr__(self, name: str) -> object:
        return getattr(self._stream, name)


@contextmanager
def guarded_streams() -> Iterator[None]:
    """In the block, standard output and error are guarded (:class:`_GuardedStream`): a
    reader gone ends the messages, not the work; another error writing standard output
    names it, and so does output written where the command was started without one (the
    block ends with that error: a failure, as ``cat >&-`` has it, once every file is
    written). What is left in their buffers is written before the block ends, so an error
    comes while the command can still say it in one line."""
    out, err = sys.stdout, sys.stderr
    guarded_out = _GuardedStream(out, "standard output", 1, False, missing=stdout_missing())
    guarded_err = _GuardedStream(err, "standard error", 2, True, missing=err is None)
    sys.stdout, sys.stderr = guarded_out, guarded_err  # type: ignore[assignment]
    try:
        yield
        sys.stderr.flush()
        sys.stdout.flush()
        if guarded_out.lost:
            raise _closed_stdout()
    finally:
        sys.stdout, sys.stderr = out, err


def _say(line: str) -> None:
    """``line`` on standard error, readably (:func:`_write_readably`); nothing where the
    command has none."""
    if sys.stderr is not None:
        with contextlib.suppress(OSError):
            _write_readably(sys.stderr, line + "\n")
            sys.stderr.flush()


def report(exc: UsageError, default_prog: str) -> int:
    """Print ``PROG: error: MESSAGE`` on stderr and return exit code 2."""
    _say(f"{exc.prog or default_prog}: error: {exc}")
    return 2


def report_os_error(exc: OSError, prog: str, unnamed: str | None = None) -> int:
    """A file the command could not write or read for a reason that is no bad input (a full
    disk, a read-only file system, an I/O error): one line naming it (``unnamed``: what to
    name where the error names no file), exit 1 (it ended in a traceback: a stranger's
    probe with a 64-kB tmpfs)."""
    where = f"{exc.filename or unnamed}: " if exc.filename or unnamed else ""
    _say(f"{prog}: error: {where}{exc.strerror or exc}")
    # a path too long or looping is the path given, bad input (exit 1 said otherwise: a probe)
    return 2 if exc.errno in (errno.ENAMETOOLONG, errno.ELOOP) else 1


def working_directory_gone() -> bool:
    """Whether the working directory has been deleted (a relative path then names
    nothing)."""
    try:
        os.getcwd()
    except FileNotFoundError:
        return True
    return False


#: What a relative path is when :func:`working_directory_gone` (it said "None: No such
#: file or directory", or "a loop of symbolic links": a stranger's probe)
_NO_WORKING_DIRECTORY = "is relative, and the working directory no longer exists"


def _refuse_relative_without_cwd(text: str) -> None:
    """An argparse ``type``'s refusal of a relative path where the working directory has
    been deleted."""
    if not os.path.isabs(text) and working_directory_gone():
        raise argparse.ArgumentTypeError(f"'{text}' {_NO_WORKING_DIRECTORY}; give an absolute path")


def path_arg(text: str) -> Path:
    """An argparse ``type`` for a file or directory path: an empty one is refused (it was
    taken as '.', and the error named '.'), and so is a relative one where the working
    directory has been deleted."""
    if not text.strip():
        raise argparse.ArgumentTypeError("an empty path")
    _refuse_relative_without_cwd(text)
    return Path(text)


def finite_float(low: float, high: float, unit: str = "") -> Callable[[str], float]:
    """An argparse ``type`` for a finite number in ``low..high`` (its error names the range)."""
    where = f"{low:g}..{high:g}{' ' + unit if unit else ''}"

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"'{text}' is not a number ({where})") from None
        if not math.isfinite(value):
            raise argparse.ArgumentTypeError(f"{text} is not a finite number ({where})")
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(f"{text} is outside {where}")
        return value

    return parse


def int_in(low: int, high: int) -> Callable[[str], int]:
    """An argparse ``type`` for a whole number in ``low..high``."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"'{text}' is not a whole number ({low}..{high})"
            ) from None
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(f"{text} is outside {low}..{high}")
        return value

    return parse


def listen_host(text: str) -> str:
    """An argparse ``type`` for an address to listen on: not empty (an empty host listens
    on every interface, which must be asked for by name: 0.0.0.0 or ::)."""
    if not text.strip():
        raise argparse.ArgumentTypeError(
            "empty; give an address (127.0.0.1, or 0.0.0.0 for every interface)"
        )
    problem = host_name_problem(text)
    if problem is not None:
        raise argparse.ArgumentTypeError(f"'{text[:80]}' is no host name ({problem})")
    return text


def text_input(text: str) -> str:
    """An argparse ``type`` for NAME-or-PATH options: a PATH that exists must be a readable
    UTF-8 text file (a NAME that is no path passes unchanged, and so does a bare word
    without a YAML suffix: a shipped NAME is the shipped file whatever the working
    directory holds, :func:`rig_emulator.yamlio.resolve_named`)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("empty (a NAME or a PATH)")
    if "/" in text or text.endswith((".yaml", ".yml")):  # (a PATH, not a NAME)
        _refuse_relative_without_cwd(text)
    path = Path(text)
    if not path.exists() or ("/" not in text and path.suffix not in (".yaml", ".yml")):
        return text
    if path.is_dir():
        raise argparse.ArgumentTypeError(f"{text} is a directory, not a file")
    if not path.is_file():  # a device (/dev/zero) would be read until memory runs out
        raise argparse.ArgumentTypeError(f"{text} is not a regular file")
    try:
        path.read_bytes().decode("utf-8")
    except OSError as exc:
        raise argparse.ArgumentTypeError(f"{text}: cannot read ({exc.strerror})") from None
    except UnicodeDecodeError as exc:
        raise argparse.ArgumentTypeError(
            f"{text} is not UTF-8 text (byte 0x{exc.object[exc.start]:02x} at {exc.start})"
        ) from None
    return text


def _no_such_file(text: str) -> argparse.ArgumentTypeError:
    """What is said of an input path that leads to no file (a link to none, or a loop of
    links, was "no such file": a stranger's probe)."""
    if Path(text).is_symlink():
        return argparse.ArgumentTypeError(
            f"{text}: a symbolic link that leads to no file (a loop?)"
        )
    return argparse.ArgumentTypeError(f"{text}: no such file")


def text_file(text: str) -> Path:
    """An argparse ``type`` for an input file that must exist and be UTF-8 text."""
    _refuse_relative_without_cwd(text)
    if not Path(text).exists():
        raise _no_such_file(text)
    return Path(text_input(text))


def data_file(text: str) -> Path:
    """An argparse ``type`` for a data file its reader decodes itself (a lab log, which may
    come from a spreadsheet in Windows-1252): it must exist and be a regular file."""
    if not text.strip():
        raise argparse.ArgumentTypeError("empty (a PATH)")
    _refuse_relative_without_cwd(text)
    path = Path(text)
    if not path.exists():
        raise _no_such_file(text)
    if path.is_dir():
        raise argparse.ArgumentTypeError(f"{text} is a directory, not a file")
    if not path.is_file():
        raise argparse.ArgumentTypeError(f"{text} is not a regular file")
    return path


def refuse_overwriting(out: Path, inputs: Mapping[str, Path | None], option: str = "--out") -> None:
    """Refuse an output that names one of the command's inputs (``inputs``: what each is,
    as the message says it; None: not given), through links: ``balance --out LOG.csv``
    wrote its JSON over the lab log, ``serve --fault-log F.yaml --faults F.yaml`` its
    journal over the fault file, ``map-doc --out MAP --map MAP`` the reference over the
    map (strangers' probes)."""
    for what, path in inputs.items():
        if path is None:
            continue
        try:
            same = out.resolve() == path.resolve() or (
                out.exists() and path.exists() and os.path.samefile(out, path)
            )
        except (OSError, RuntimeError):  # (a loop: reported where the path is used)
            continue
        if same:
            raise UsageError(f"{option}: '{out}' is {what}, which it would overwrite; name another")


#: The installed packages' directories (their shipped boilers, profiles, maps, protocols):
#: no output goes there
_PACKAGE_ROOTS = tuple(
    root
    for root in (
        Path(__file__).resolve().parent,
        Path(__file__).resolve().parents[1] / "hil_client",
    )
    if root.is_dir()
)


def output_file(path: Path, option: str = "--out") -> Path:
    """``path``, its missing parent directories created (as ``--out`` users expect);
    a parent that is a file, or a ``path`` that is a directory or a loop of symbolic links,
    is a :class:`UsageError` (``option``: the option its message names), and so is a
    ``path`` no output can go to (:func:`_check_destination`: a FIFO without a reader, a
    socket; a name too long, :func:`_check_name_length`; a directory that takes no new
    file, :func:`_check_writable`), and a relative ``path`` where the working directory
    has been deleted."""
    if not path.is_absolute() and working_directory_gone():
        raise UsageError(f"{option}: '{path}' {_NO_WORKING_DIRECTORY}; give an absolute path")
    try:
        real = path.resolve()
    except (RuntimeError, OSError):  # (a traceback: a stranger's probe)
        raise UsageError(f"{option}: '{path}' is a loop of symbolic links") from None
    _check_name_length(path, real, option)
    if any(real.is_relative_to(root) for root in _PACKAGE_ROOTS):  # (the shipped map or
        raise UsageError(  # boiler a NAME resolves to was replaced: a re-probe)
            f"{option}: '{path}' lies in the installed package (its shipped data); name another"
        )
    if path.is_dir():
        raise UsageError(f"{option}: '{path}' is a directory")
    _check_destination(path, option)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UsageError(f"{option}: cannot create '{path.parent}' ({exc.strerror})") from None
    _check_writable(path, real, option)
    return path


def _check_name_length(path: Path, real: Path, option: str) -> None:
    """Refuse a ``path`` (``real``: resolved, where a link's file is written) whose file
    name is longer than the file system of its directory (or of the nearest one there)
    allows. Found while writing, it was exit 1 after the work began ("cannot write
    NAME.meta.json: File name too long" of a log whose own name fitted), where a name too
    long for the log itself was exit 2 (a stranger's probe): a path given that cannot be
    written is bad input, judged before any work."""
    size = len(os.fsencode(real.name))
    for directory in real.parents:
        try:
            longest = os.pathconf(directory, "PC_NAME_MAX")
        except (OSError, ValueError):  # not there yet (created later), or no limit to tell
            continue
        if size > longest:
            raise UsageError(
                f"{option}: '{path}': the file name is too long ({size} bytes, at most {longest})"
            )
        return


def _check_writable(path: Path, real: Path, option: str) -> None:
    """Refuse a ``path`` (``real``: resolved, where a link's file is written) whose
    directory takes no new file (read-only, no permission) where ``path`` is no file
    already writable in place: before any work, as a missing directory that cannot be
    created is (exit 2), not while writing after it ("cannot write x.csv: Permission
    denied", exit 1: a stranger's probe)."""
    directory = real.parent
    if os.access(directory, os.W_OK | os.X_OK) or os.access(real, os.W_OK):
        return
    why = "read-only file system" if _read_only(directory) else "no permission"
    raise UsageError(
        f"{option}: cannot write '{path}': its directory '{directory}' takes no new file ({why})"
    )


def _read_only(directory: Path) -> bool:
    """Whether ``directory`` lies on a file system mounted read-only."""
    try:
        return bool(os.statvfs(directory).f_flag & os.ST_RDONLY)
    except OSError:
        return False


#: What an output that exists may be besides a regular file or a FIFO: a character device
#: (``/dev/null``, ``/dev/full``: a clear line and exit 1, a terminal, ``/dev/stdout``)
_NOT_WRITABLE = {stat.S_IFSOCK: "a socket", stat.S_IFBLK: "a block device"}

#: The write ends of the FIFOs :func:`output_file` found read, by path: held open until
#: :func:`release_outputs` (see :func:`_hold_reader`)
_HELD_WRITERS: dict[str, int] = {}


def _check_destination(path: Path, option: str) -> None:
    """Refuse an existing ``path`` that is no file to write: a socket or a block device, or
    a FIFO no process reads (:func:`_hold_reader`)."""
    try:
        mode = path.stat().st_mode
    except OSError:  # not there (its writer creates it), or a dangling link
        return
    if stat.S_ISFIFO(mode):
        _hold_reader(path, option)
    elif not (stat.S_ISREG(mode) or stat.S_ISCHR(mode)):
        kind = _NOT_WRITABLE.get(stat.S_IFMT(mode), "not a regular file")
        raise UsageError(f"{option}: '{path}' is {kind}; name a file")


def _hold_reader(fifo: Path, option: str) -> None:
    """Check, without waiting, that a process reads ``fifo`` (a journal or report streamed
    through a named pipe), and hold a write end of it open until :func:`release_outputs`.

    A FIFO no process read blocked the open for good: ``serve --fault-log FIFO`` listened
    on its port, then hung deaf to SIGINT and SIGTERM, ``balance --out FIFO`` waited
    forever (a stranger's probe). Closed at once, the check would end the reader's stream
    before the command writes (``cat FIFO`` stops when the last writer closes), and the
    command's own open of the path would wait for a reader again; held, that open finds
    the reader still there."""
    key = str(fifo.absolute())
    if key in _HELD_WRITERS:
        return
    try:
        _HELD_WRITERS[key] = open_without_waiting(fifo)
    except OSError as exc:
        if exc.errno == errno.ENXIO:
            raise UsageError(
                f"{option}: no process reads the FIFO '{fifo}'; start its reader first"
            ) from None
        raise UsageError(f"{option}: cannot write '{fifo}' ({exc.strerror})") from None


def release_outputs() -> None:
    """Close the FIFO write ends :func:`output_file` held: their readers see the end of the
    stream once the command's own writes are closed too (call it when the command ends)."""
    while _HELD_WRITERS:
        _, fd = _HELD_WRITERS.popitem()
        with contextlib.suppress(OSError):
            os.close(fd)


@contextmanager
def input_errors() -> Iterator[None]:
    """The last line of defence of both CLIs: unreadable or undecodable input files in the
    block become one-line :class:`UsageError` s instead of tracebacks."""
    try:
        yield
    except UnicodeDecodeError as exc:
        raise UsageError(
            f"an input file is not UTF-8 text (byte 0x{exc.object[exc.start]:02x} at {exc.start})"
        ) from None
    except FileNotFoundError as exc:
        if exc.filename is None and working_directory_gone():  # (os.getcwd's error: "None:
            raise UsageError(  # No such file or directory", a stranger's probe; absolute
                # paths do not help where a library asks for it, numba's compiler: a re-probe)
                "the working directory no longer exists, and this command needs one: run it "
                "from a directory that exists"
            ) from None
        raise UsageError(f"{exc.filename}: {exc.strerror}") from None
    except (IsADirectoryError, NotADirectoryError, PermissionError) as exc:
        raise UsageError(f"{exc.filename}: {exc.strerror}") from None
