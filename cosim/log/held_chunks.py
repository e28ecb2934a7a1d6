"""The stream an MCAP writer writes a log through: only finished records reach the file.

foxglove-sdk's MCAP writer (the Rust ``mcap`` crate) opens a chunk by writing its record
header with placeholder lengths (all ones), writes the chunk's compressed data when the
chunk is full, then seeks back to fill the lengths in and returns to the end, where the
chunk's message indexes follow. A process killed with a chunk open would leave a record
claiming 2^64 - 1 bytes, which stops every reader at the start of it, the chunks before
included for a streaming reader (``mcap``'s ``StreamReader`` raises there).

:class:`HeldChunks` holds in memory what follows the last finished record and writes it
to the file (and flushes it to the operating system) when it is finished: when a chunk
is filled in and the writer returns to the end, when the next chunk opens, and on the
writer's ``flush`` (which ends the open chunk: :meth:`McapRecorder.publish`) and ``close``.
So a killed run's log holds every chunk finished before it was killed, readable by every
MCAP reader, as the MCAP specification's chunked layout intends (https://mcap.dev/spec);
it loses the chunk being filled, about ``chunk_size_bytes`` of messages.

A write that fails (a full disk) is not raised into the writer, which would log it and
carry on: it is kept in :attr:`HeldChunks.error`, nothing more is written, and the
recorder raises it at its next message, so the run ends with one line and what reached
the disk stays readable.
"""

from __future__ import annotations

from typing import IO

CHUNK_OPCODE = 0x06
"""The MCAP record opcode of a chunk."""
RECORD_PREFIX_BYTES = 9
"""Opcode (1 byte) and record length (8): written alone when a record opens."""


class HeldChunks:
    """A seekable binary stream over ``file`` that holds back unfinished records."""

    def __init__(self, file: IO[bytes]) -> None:
        self._file = file
        self._committed = 0
        """Bytes in the file."""
        self._held = bytearray()
        """What follows them, not yet finished."""
        self._position = 0
        self._open_chunk: int | None = None
        """Where the chunk being filled starts (None: no chunk open)."""
        self._filled_in = False
        """The open chunk's header was written again (its lengths filled in)."""
        self._discarded = False
        self.error: OSError | None = None
        """The first write to the file that failed (nothing is written after it)."""

    def write(self, data: bytes | bytearray | memoryview) -> int:
        if self._discarded:  # the writer finishes into nothing
            self._position += len(data)
            self._committed = max(self._committed, self._position)
            return len(data)
        offset = self._position - self._committed
        if offset < 0 or offset > len(self._held):
            raise OSError(f"the MCAP writer wrote at byte {self._position}, outside the "
                          f"part it has not finished ({self._committed} on)")
        size = len(data)
        if offset == len(self._held) and self._open_chunk is None and \
                size == RECORD_PREFIX_BYTES and data[0] == CHUNK_OPCODE:
            self._commit_or_keep_error()  # a chunk opens: everything before it is finished
            offset = 0
            self._open_chunk = self._position
        elif self._position == self._open_chunk:
            self._filled_in = True
        self._held[offset:offset + size] = data
        self._position += size
        return size

    def seek(self, offset: int, whence: int = 0) -> int:
        end = self._committed + len(self._held)
        target = (offset, self._position + offset, end + offset)[whence]
        if self._filled_in and target == end and target != self._position:
            self._open_chunk, self._filled_in = None, False
            self._position = target
            self._commit_or_keep_error()  # the chunk is finished
        self._position = target
        return target

    def tell(self) -> int:
        return self._position

    def flush(self) -> None:
        """The writer's flush: what it holds is finished unless a chunk is open."""
        if self._open_chunk is None:
            self._commit_or_keep_error()

    def commit(self) -> None:
        """Write what is held to the file and flush it to the operating system."""
        if self._held and not self._discarded:
            self._file.write(self._held)
            self._file.flush()
        self._committed += len(self._held)
        self._held = bytearray()

    def _commit_or_keep_error(self) -> None:
        """:meth:`commit` from inside the writer: a failure is kept, not raised."""
        try:
            self.commit()
        except OSError as error:
            self.error = error
            self.discard()

    def discard(self) -> None:
        """Write nothing more to the file (its run was abandoned)."""
        self._discarded = True
        self._committed += len(self._held)
        self._held = bytearray()
