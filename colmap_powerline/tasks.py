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
import logging
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar, TypeVar

from tqdm import tqdm

from .errors import InputError
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

    LIMITS: ClassVar[dict[str, str]] = {"workers": ">= 0"}

    def __post_init__(self) -> None:
        check_limits(self)


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
    ) -> list[T]:
        """``[fn(item, *shared) for item in items]``, in the items' order. On Dask the
        ``shared`` arguments are sent to each worker once, not with every piece."""
        bar = tqdm(total=len(items), desc=desc, unit=unit, disable=not show_progress)
        with bar:
            if self._client is None:
                out = []
                for item in items:
                    out.append(fn(item, *shared))
                    bar.update()
                return out
            from distributed import as_completed

            level = logging.getLogger(PACKAGE).getEffectiveLevel()
            sent = [self._client.scatter(s, broadcast=True) for s in shared]
            futures = self._client.map(
                _logged,
                [fn] * len(items),
                [level] * len(items),
                list(items),
                *[[s] * len(items) for s in sent],
                pure=False,
            )
            for _ in as_completed(futures):
                bar.update()
            out = []
            for result, records in self._client.gather(futures):
                for record in records:
                    logging.getLogger(record.name).handle(record)
                out.append(result)
            return out


PACKAGE = __name__.rsplit(".", 1)[0]


class _Records(logging.Handler):
    """Keeps the records a task logs, their messages formatted (their arguments may not
    travel back from a worker)."""

    def __init__(self) -> None:
        super().__init__()
        self.records: list[logging.LogRecord] = []

    def emit(self, record: logging.LogRecord) -> None:
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
