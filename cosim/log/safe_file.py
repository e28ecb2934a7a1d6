"""Writing a log without ever destroying a user's file.

A log is written to a hidden temporary name in the folder of its final name
(``.NAME.<pid>.partial``) and renamed into place (``os.replace``, atomic on one file
system) only when the run has started for real: after the plant was built and settled, the
sensors, faults, filter and tracker were made and the header was written. A run refused
before that (a bad fault channel, physics diverging while the car settles, Ctrl-C during
set-up, a full disk) removes its temporary file and leaves whatever was at the final name
untouched.

What a SIGKILL leaves: killed during set-up, a ``.NAME.<pid>.partial`` file beside the
final name (the final name untouched); killed once the run has started, the log at its
final name, complete up to the last chunk written (``cosim inspect`` reads it and says it is
truncated). The file descriptor stays open across the rename, so the writer goes on into
the same file.

:func:`check_output_path` refuses an ``--out`` that names an existing file (unless
``force``), a folder, or one of the run's own input files (a config or scenario file).
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path
from typing import IO

from cosim.core.exceptions import ConfigError


def partial_path(path: Path) -> Path:
    """The temporary name a log is written under before it is renamed to ``path``."""
    return path.with_name(f".{path.name}.{os.getpid()}.partial")


def _same_file(a: Path, b: Path) -> bool:
    try:
        return a.exists() and b.exists() and os.path.samefile(a, b)
    except OSError:
        return False


def check_output_path(path: Path, option: str, force: bool,
                      inputs: Iterable[str | Path | None] = ()) -> None:
    """Refuse to write ``path`` where that would destroy a file the user cares about."""
    for source in inputs:
        if source is not None and _same_file(path, Path(source)):
            raise ConfigError(f"{option} {str(path)!r}: is the input file {str(source)!r}; "
                              "expected another file name")
    if path.is_dir():
        raise ConfigError(f"{option} {str(path)!r}: is a folder; expected a file name")
    if path.exists() and not force:
        force_option = "--force" if option.startswith("--") else "force=True"
        raise ConfigError(f"{option} {str(path)!r}: exists; expected a new file name "
                          f"(or {force_option} to replace it)")


class PendingFile:
    """A binary file written under :func:`partial_path` and published to its final name.

    ``publish()`` renames it into place (the handle stays open); ``close(keep=False)``
    before publishing removes the temporary file.
    """

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self.temporary = partial_path(self.path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.file: IO[bytes] = open(self.temporary, "wb")  # noqa: SIM115 - closed in close()
        self.published = False

    def publish(self) -> None:
        """Rename the temporary file to the final name (atomic; once)."""
        if not self.published:
            os.replace(self.temporary, self.path)
            self.published = True

    def close(self) -> None:
        """Close; an unpublished file is removed (the final name was never touched)."""
        try:
            self.file.close()
        finally:
            if not self.published:
                self.temporary.unlink(missing_ok=True)
