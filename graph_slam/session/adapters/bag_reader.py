"""Opening bags with ``rosbags``: a reader whose failures become :class:`BagError` with a hint
on how to repair the bag (reindex, recover)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

from graph_slam.errors import BagError, ConversionError, MissingStreamError

INSTALL_HINT = "reading bags needs the optional package 'rosbags': pip install graph_slam[bags]"


def _rosbags():
    """Import rosbags lazily; a clear error when the optional extra is missing."""
    try:
        from rosbags.highlevel import AnyReader
    except ImportError:
        raise ConversionError(INSTALL_HINT) from None
    return AnyReader


def _ros2_typestore():
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_HUMBLE)


def _rosbag_errors() -> tuple[type[BaseException], ...]:
    import sqlite3
    import struct

    from rosbags.highlevel import AnyReaderError
    from rosbags.rosbag1 import ReaderError as Reader1Error
    from rosbags.rosbag2 import ReaderError as Reader2Error
    from rosbags.serde import SerdeError

    return (
        AnyReaderError,
        Reader1Error,
        Reader2Error,
        SerdeError,
        sqlite3.DatabaseError,
        struct.error,
        EOFError,
        # rosbags on random or damaged bytes (found by tests/test_faults_fuzz.py): a header
        # that is not UTF-8, a record length past the end, a field it does not know
        UnicodeDecodeError,
        ValueError,
        IndexError,
        KeyError,
        OverflowError,
        OSError,  # a seek to a negative offset (a damaged index position)
        AssertionError,  # rosbags' own consistency checks on a damaged chunk
    )


def _hint(message: str, path: Path) -> str:
    text = message.lower()
    if "not indexed" in text:
        return (
            "the bag has no index (an interrupted recording?); rebuild it with "
            f"`rosbag reindex {path.name}` (ROS 1 tools), then convert again"
        )
    if "malformed" in text or "not a database" in text:
        return (
            "the SQLite file is damaged or truncated; recover what is left with sqlite3's "
            "`.recover`, or re-record"
        )
    if "magic" in text and path.suffix != ".bag":
        return (
            "the MCAP file is truncated or damaged; `mcap recover IN.mcap -o OUT.mcap` "
            "rewrites what is readable"
        )
    if "magic" in text:
        return "this is not a ROS 1 bag (wrong file magic)"
    return (
        "the bag looks truncated or damaged; `rosbag reindex FILE` rebuilds the index of a "
        "truncated ROS 1 bag, `ros2 bag reindex DIR` the metadata of a ROS 2 bag"
    )


def _bag_error(path: Path, err: BaseException) -> BagError:
    message = " ".join(str(a) for a in err.args) or type(err).__name__
    if isinstance(err, UnicodeDecodeError):
        message = f"byte {err.start} is not text where the bag's header should be"
    message = message if len(message) <= 200 else message[:200] + "..."
    return BagError(f"{path}: cannot read the bag ({message}); {_hint(message, path)}")


def bag_path(path: Path) -> Path:
    """The path to give rosbags (a .bag file, a .db3/.mcap file, or a ROS 2 folder)."""
    path = Path(path)
    if path.is_file():
        if path.suffix in (".bag", ".db3", ".mcap"):
            return path
        if path.name.endswith(".bag.active"):
            raise BagError(
                f"{path}: an unfinished recording (.bag.active has no index); rebuild it with "
                f"`rosbag reindex {path.name}` (ROS 1 tools) and rename it to .bag"
            )
        raise ConversionError(f"{path}: not a bag (expected .bag, .db3, .mcap or a ROS 2 folder)")
    if path.is_dir():
        if (path / "metadata.yaml").is_file():
            return path
        storage = sorted(p.name for p in path.iterdir() if p.suffix in (".db3", ".mcap"))
        if storage:
            raise BagError(
                f"{path}: ROS 2 bag folder without metadata.yaml; `ros2 bag reindex {path}` "
                f"rebuilds it, or convert the storage file itself ({storage[0]})"
            )
        raise ConversionError(f"{path}: not a ROS 2 bag folder (no metadata.yaml)")
    raise MissingStreamError(f"{path}: no such file or folder")


class Bag:
    """An open rosbags reader whose failures become :class:`BagError` with a hint."""

    def __init__(self, path: Path) -> None:
        self.path = path
        any_reader = _rosbags()
        self._errors = _rosbag_errors()
        try:
            # The RealSense SDK's .db3 recordings carry no message definitions: the standard
            # ROS 2 types are brought along (used only for types a bag does not define).
            self.reader = any_reader([bag_path(path)], default_typestore=_ros2_typestore())
            self.reader.open()
        except FileNotFoundError as err:
            raise _bag_error(path, err) from None
        except self._errors as err:
            raise _bag_error(path, err) from None
        self.is_ros2 = bool(self.reader.is2)

    def close(self) -> None:
        if self.reader.stack is not None:
            self.reader.close()

    def __enter__(self) -> Bag:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def topics(self) -> dict[str, str | None]:
        return {name: info.msgtype for name, info in self.reader.topics.items()}

    def counts(self) -> dict[str, int]:
        return {name: int(info.msgcount) for name, info in self.reader.topics.items()}

    def messages(self, topics: set[str]) -> Iterator[tuple[str, int, Any]]:
        """(topic, bag time ns, decoded message) in bag time order."""
        conns = [c for c in self.reader.connections if c.topic in topics]
        gen = self.reader.messages(connections=conns)
        while True:
            try:
                conn, bag_ns, raw = next(gen)
                msg = self.reader.deserialize(raw, conn.msgtype)
            except StopIteration:
                return
            except self._errors as err:
                raise _bag_error(self.path, err) from None
            yield conn.topic, int(bag_ns), msg
