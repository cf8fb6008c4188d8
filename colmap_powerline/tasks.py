"""Where independent pieces of work run: in this process, or as Dask tasks.

A run is made of pieces that do not depend on each other: each image pair's rectification,
wire detection and triangulation reads only its two images. :class:`Tasks` maps a function
over such pieces and returns the results in the pieces' order, whether they ran here one
after the other or on Dask workers (a local cluster with ``workers``, or a running
scheduler with ``scheduler``: a Kubernetes or SLURM cluster started with dask-kubernetes
or dask-jobqueue). The order of the results never depends on where or when a piece ran,
so the outputs are the same with any number of workers.
"""

from __future__ import annotations

import contextlib
import hashlib
import logging
import pickle
import shutil
import threading
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar, TypeVar

from tqdm import tqdm

from .errors import InputError
from .files import write_atomic
from .options import check_limits

logger = logging.getLogger(__name__)

T = TypeVar("T")


@dataclass(frozen=True)
class ExecutionOptions:
    """Where the pieces of a run execute (they give the same outputs wherever they run)."""

    workers: int = field(
        default=0,
        metadata={
            "help": "Dask workers to start on this machine, one process each (0: run "
            "everything in this process)"
        },
    )
    scheduler: str | None = field(
        default=None,
        metadata={
            "help": "address of a running Dask scheduler (tcp://host:8786) whose workers "
            "run the pieces instead; they must see the images at the same paths"
        },
    )

    redo: bool = field(
        default=False,
        metadata={
            "help": "redo every piece: do not take the pieces a run with the same inputs and "
            "options finished before from OUTPUT/.pieces/"
        },
    )

    LIMITS: ClassVar[dict[str, str]] = {"workers": ">= 0"}

    def __post_init__(self) -> None:
        check_limits(self)


class Store:
    """Finished pieces of a run, kept on disk (one pickle each, written whole or not at
    all) until the run's outputs are written, so that the same run started again does not
    redo them: a run cut short loses only the pieces that were in flight. ``folder`` is
    named by :func:`run_key`: another input or option is another folder."""

    def __init__(self, folder: Path, redo: bool = False) -> None:
        self.folder = Path(folder)
        self.redo = redo

    def _path(self, name: str) -> Path:
        return self.folder / f"{name}.pkl"

    def load(self, name: str) -> tuple[bool, Any]:
        """(True, the piece) when it was kept (and ``redo`` is off), else (False, None)."""
        path = self._path(name)
        if self.redo or not path.is_file():
            return False, None
        try:
            return True, pickle.loads(path.read_bytes())
        except Exception as e:  # a piece from another version of the package: redone
            logger.warning("resume: %s unreadable (%s); redoing it", path, e)
            return False, None

    def save(self, name: str, value: Any) -> None:
        data = pickle.dumps(value, protocol=pickle.HIGHEST_PROTOCOL)
        write_atomic(self._path(name), lambda p: p.write_bytes(data))

    def clear(self) -> None:
        """Remove every kept piece (and ``.pieces/`` when nothing else is in it)."""
        shutil.rmtree(self.folder, ignore_errors=True)
        with contextlib.suppress(OSError):
            self.folder.parent.rmdir()

    def get(self, name: str, compute: Callable[[], T]) -> T:
        """The kept piece ``name``, or ``compute()`` kept."""
        found, value = self.load(name)
        if found:
            logger.info("resume: %s taken from %s", name, self.folder)
            return value
        value = compute()
        self.save(name, value)
        return value


def run_key(model_path: Path, image_paths: Sequence[Path], *more: Any) -> str:
    """A digest of what a run's pieces depend on: the model's files (their bytes), each
    image's path, size and modification time, the package's version and ``more`` (the
    options, as text)."""
    from . import __version__

    h = hashlib.sha256(__version__.encode())
    for f in sorted(Path(model_path).iterdir()):
        if f.is_file() and f.suffix in (".bin", ".txt", ".json"):
            h.update(f.name.encode())
            with f.open("rb") as fh:
                for chunk in iter(lambda: fh.read(1 << 20), b""):
                    h.update(chunk)
    for p in image_paths:
        st = Path(p).stat()
        h.update(f"{p}|{st.st_size}|{st.st_mtime_ns}".encode())
    for m in more:
        h.update(repr(m).encode())
    return h.hexdigest()[:16]


def digest(obj: Any) -> str:
    """A short digest of a piece's own description (its ``repr``)."""
    return hashlib.sha256(repr(obj).encode()).hexdigest()[:12]


class Tasks:
    """Maps a function over independent pieces of work, here or on Dask workers."""

    def __init__(self, client: Any = None) -> None:
        self._client = client

    @property
    def distributed(self) -> bool:
        return self._client is not None

    def map(
        self,
        fn: Callable[..., T],
        items: Sequence[Any],
        *shared: Any,
        desc: str = "",
        unit: str = "it",
        show_progress: bool = False,
        store: Store | None = None,
        names: Sequence[str] | None = None,
    ) -> list[T]:
        """``[fn(item, *shared) for item in items]``, in the items' order. On Dask the
        ``shared`` arguments are sent to each worker once, not with every piece. With a
        ``store``, the pieces it keeps under ``names`` are taken from it, and each piece done
        is kept as soon as it is done."""
        out: list[Any] = [None] * len(items)
        todo = list(range(len(items)))
        if store is not None and names is not None:
            todo = []
            for i, name in enumerate(names):
                found, value = store.load(name)
                if found:
                    out[i] = value
                else:
                    todo.append(i)
            if len(todo) < len(items):
                logger.info(
                    "resume: %d of %d %ss taken from %s",
                    len(items) - len(todo),
                    len(items),
                    unit,
                    store.folder,
                )

        def keep(i: int, value: Any) -> None:
            out[i] = value
            if store is not None and names is not None:
                store.save(names[i], value)

        bar = tqdm(total=len(todo), desc=desc, unit=unit, disable=not show_progress)
        with bar:
            if self._client is None:
                for i in todo:
                    keep(i, fn(items[i], *shared))
                    bar.update()
                return out
            from distributed import as_completed

            level = logging.getLogger(PACKAGE).getEffectiveLevel()
            sent = [self._client.scatter(s, broadcast=True) for s in shared]
            futures = self._client.map(
                _logged,
                [fn] * len(todo),
                [level] * len(todo),
                [items[i] for i in todo],
                *[[s] * len(todo) for s in sent],
                pure=False,
            )
            index = {f.key: i for f, i in zip(futures, todo, strict=True)}
            logs: dict[int, list[logging.LogRecord]] = {}
            for future in as_completed(futures):
                value, records = future.result()
                logs[index[future.key]] = records
                keep(index[future.key], value)
                bar.update()
        for i in todo:
            for record in logs[i]:
                logging.getLogger(record.name).handle(record)
        return out


PACKAGE = __name__.rsplit(".", 1)[0]


class _Records(logging.Handler):
    """Keeps the records a task logs from its own thread (a worker with several threads
    runs several tasks at once), their messages formatted (their arguments may not travel
    back from a worker)."""

    def __init__(self) -> None:
        super().__init__()
        self.records: list[logging.LogRecord] = []
        self.thread = threading.get_ident()

    def emit(self, record: logging.LogRecord) -> None:
        if record.thread != self.thread:
            return
        record.msg, record.args = record.getMessage(), None
        record.exc_info = record.exc_text = None
        self.records.append(record)


def _logged(
    fn: Callable[..., T], level: int, item: Any, *shared: Any
) -> tuple[T, list[logging.LogRecord]]:
    """``fn(item, *shared)`` on a worker, with what it logged at ``level`` and above (the
    run's level), to be logged where the run is, in the pieces' order."""
    logger_ = logging.getLogger(PACKAGE)
    handler = _Records()
    old_level, old_propagate = logger_.level, logger_.propagate
    logger_.addHandler(handler)
    logger_.setLevel(level)
    logger_.propagate = False  # not also to the worker's own log
    try:
        return fn(item, *shared), handler.records
    finally:
        logger_.removeHandler(handler)
        logger_.setLevel(old_level)
        logger_.propagate = old_propagate


@contextlib.contextmanager
def tasks_for(options: ExecutionOptions | None) -> Iterator[Tasks]:
    """The :class:`Tasks` of a run: in this process (``workers`` 0, no scheduler), on a
    local Dask cluster of ``workers`` processes, or on the cluster of ``scheduler``."""
    options = options or ExecutionOptions()
    if options.scheduler is None and options.workers == 0:
        yield Tasks()
        return
    try:
        from distributed import Client, LocalCluster
    except ImportError as e:  # pragma: no cover - a dependency of the package
        raise InputError(f"--workers/--scheduler need dask.distributed: {e}") from e
    if options.scheduler is not None:
        try:
            client = Client(options.scheduler, timeout="10s")
        except OSError as e:
            raise InputError(f"no Dask scheduler at {options.scheduler}: {e}") from e
        with client:
            logger.info("tasks: on the Dask cluster at %s", options.scheduler)
            yield Tasks(client)
        return
    with (
        LocalCluster(
            n_workers=options.workers,
            threads_per_worker=1,
            processes=True,
            dashboard_address=None,
            silence_logs=logging.WARNING,
        ) as cluster,
        Client(cluster) as client,
    ):
        logger.info("tasks: on %d local Dask workers", options.workers)
        yield Tasks(client)
