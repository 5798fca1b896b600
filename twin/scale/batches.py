"""Many independent pieces of work (draws, vessels, logs) split into seeded batches and run by an
executor: in this process on the batch engine with every core (`LocalExecutor`), or as tasks on
a Ray cluster (`RayExecutor`, the optional `cluster` extra).

Why batches and not one task per item: a batch is what the batch engine runs well (one
`mujoco.rollout` over tens of twins) and what makes a cluster's per-task cost (scheduling, a
few hundred kB back) negligible against seconds of simulation. Why seeded per batch: batch i
draws from `SeedSequence(seed, spawn_key=(i,))` whoever runs it, and the batch size is a
setting of the job, not of the machine; so the results are the same bits locally and on any
cluster, in any order the batches finish, and a batch that is run again (a retried task)
draws the same numbers.

A task is a plain module-level function `task(payload, batch, extra) -> result`: `payload` is
what every batch shares (sent once: Ray's object store), `extra` what only this batch needs
(a log's bytes), made when the batch is submitted so that a long job never holds all of it.
Rollouts inside a task use the CPUs the executor grants it (`engine.batch.thread_limit`).
"""
from __future__ import annotations

import logging
import math
import os
import socket
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterator, Protocol, Sequence

import numpy as np

from ..engine.batch import thread_limit
from ..errors import TwinError
from ..progress import Progress, steps

Task = Callable[[Any, "Batch", Any], Any]
PerBatch = Callable[["Batch"], Any]


@dataclass(frozen=True)
class Batch:
    """Items start..stop-1 of a job whose root seed is `seed`; batch number `index`."""

    index: int
    start: int
    stop: int
    seed: int

    @property
    def size(self) -> int:
        return self.stop - self.start

    def rng(self) -> np.random.Generator:
        """This batch's own random numbers: the index-th child of the job's seed, the same as
        `SeedSequence(seed).spawn(n)[index]` for any n > index."""
        return np.random.default_rng(np.random.SeedSequence(self.seed, spawn_key=(self.index,)))


def plan(n_items: int, batch_size: int, seed: int) -> list[Batch]:
    """n_items split into batches of batch_size (the last one shorter), seeded from `seed`."""
    if n_items < 1:
        raise TwinError(f"nothing to run: {n_items} items")
    if batch_size < 1:
        raise TwinError(f"batch size must be at least 1, got {batch_size}")
    if seed < 0:
        raise TwinError(f"seed must be ≥ 0, got {seed}")
    return [Batch(i, start, min(start + batch_size, n_items), seed)
            for i, start in enumerate(range(0, n_items, batch_size))]


def call(task: Task, payload: Any, batch: Batch, extra: Any, nthread: int | None) -> Any:
    """One batch as a worker runs it: rollouts limited to the worker's CPUs."""
    if nthread is None:
        return task(payload, batch, extra)
    with thread_limit(nthread):
        return task(payload, batch, extra)


class Executor(Protocol):
    """Runs a task over batches; yields (batch, result) as each finishes, in any order."""

    name: str

    def run(self, task: Task, payload: Any, batches: Sequence[Batch], per_batch: PerBatch | None = None,
            progress: Progress | None = None) -> Iterator[tuple[Batch, Any]]: ...


def gather(executor: Executor, task: Task, payload: Any, batches: Sequence[Batch],
           per_batch: PerBatch | None = None, progress: Progress | None = None) -> list[Any]:
    """Every batch's result, in batch order whatever order they finished in."""
    position = {b.index: k for k, b in enumerate(batches)}
    out: list[Any] = [None] * len(batches)
    for b, result in executor.run(task, payload, batches, per_batch, progress):
        out[position[b.index]] = result
    return out


@dataclass(frozen=True)
class LocalExecutor:
    """Batches one after another in this process, each on `nthread` threads (None: every core)."""

    nthread: int | None = None
    name: str = "local"

    def run(self, task: Task, payload: Any, batches: Sequence[Batch], per_batch: PerBatch | None = None,
            progress: Progress | None = None) -> Iterator[tuple[Batch, Any]]:
        say = steps(progress)
        for done, b in enumerate(batches):
            say(f"batch {done + 1} of {len(batches)}", done, len(batches))
            yield b, call(task, payload, b, per_batch(b) if per_batch else None, self.nthread)
        say("done", len(batches), len(batches))


@dataclass(frozen=True)
class RayExecutor:
    """Batches as Ray tasks of `cpus_per_task` CPUs each.

    address: "auto" (the cluster this machine belongs to: `ray start --head` or a worker node),
    "local" (a private Ray on this machine's cores, stopped afterwards), "ray://HOST:10001" (Ray
    Client) or "HOST:6379". A task whose worker process or node dies is run again, up to
    `max_retries` times, by Ray (its batch draws the same numbers again); an error the task
    raises itself (bad input) is not retried. At most `in_flight` tasks are submitted at once
    (default: two per CPU of the cluster), so a long job keeps little in the object store."""

    address: str = "auto"
    cpus_per_task: int = 1
    max_retries: int = 3
    in_flight: int | None = None
    name: str = "ray"
    init_options: dict = field(default_factory=dict)

    def run(self, task: Task, payload: Any, batches: Sequence[Batch], per_batch: PerBatch | None = None,
            progress: Progress | None = None) -> Iterator[tuple[Batch, Any]]:
        ray = ray_module()
        if self.cpus_per_task < 1 or self.max_retries < 0:
            raise TwinError("--cpus-per-task must be ≥ 1 and --retries ≥ 0")
        started = connect(ray, self.address, self.init_options)
        try:
            yield from self._run(ray, task, payload, batches, per_batch, steps(progress))
        finally:
            if started:
                ray.shutdown()

    def _run(self, ray, task, payload, batches, per_batch, say) -> Iterator[tuple[Batch, Any]]:
        remote = ray.remote(call).options(num_cpus=self.cpus_per_task, max_retries=self.max_retries,
                                          retry_exceptions=False)
        shared = ray.put(payload)
        limit = self.in_flight or max(2, int(2 * cluster_cpus(ray) // self.cpus_per_task))
        queue = iter(batches)
        pending: dict[Any, Batch] = {}
        done = 0
        try:
            while True:
                while len(pending) < limit and (b := next(queue, None)) is not None:
                    extra = per_batch(b) if per_batch else None
                    pending[remote.remote(task, shared, b, extra, self.cpus_per_task)] = b
                if not pending:
                    break
                ready, _ = ray.wait(list(pending), num_returns=1)
                b = pending.pop(ready[0])
                result = self._get(ray, ready[0], b)
                done += 1
                say(f"batch {done} of {len(batches)} ({self.name})", done, len(batches))
                yield b, result
        finally:
            for ref in pending:  # an error or an interrupt: no orphan tasks left on the cluster
                ray.cancel(ref, force=True)

    def _get(self, ray, ref, b: Batch):
        try:
            return ray.get(ref)
        except ray.exceptions.RayTaskError as exc:
            cause = getattr(exc, "cause", None)
            if isinstance(cause, TwinError):
                raise TwinError(str(cause)) from None
            first = str(cause or exc).strip().splitlines()
            raise TwinError(f"batch {b.index} (items {b.start}-{b.stop - 1}) failed on the cluster: "
                            f"{type(cause or exc).__name__}: {first[-1] if first else ''}") from None
        except ray.exceptions.RayError as exc:
            text = str(exc).strip().splitlines()
            raise TwinError(f"batch {b.index} (items {b.start}-{b.stop - 1}) lost on the cluster after "
                            f"{self.max_retries} retries: {type(exc).__name__}: {text[0] if text else ''}") from None


def ray_module():
    """Ray, or a one-line error saying how to install it."""
    try:
        import ray  # optional extra [cluster]: imported only when --ray is given
    except ImportError:
        raise TwinError("--ray needs Ray: pip install 'asv-twin[cluster]' (or pip install -e \".[cluster]\")") \
            from None
    if not hasattr(ray, "init"):  # a folder named ray (Ray's own /tmp/ray) read as a namespace package
        raise TwinError(f"--ray needs Ray, and 'ray' here is not it but a folder ({', '.join(ray.__path__)}): "
                        "pip install 'asv-twin[cluster]', or run from another folder")
    return ray


RAY_AUTH_LOGGER = "ray._private.authentication.authentication_token_setup"


class _DefaultAuthNotice(logging.Filter):
    """Drops Ray's notice that a private instance runs with token authentication: its default,
    which it would print on every `--ray local` command; its other warnings pass."""

    def filter(self, record: logging.LogRecord) -> bool:
        return not record.getMessage().startswith("Token authentication is enabled for this Ray cluster")


def connect(ray, address: str, init_options: dict | None = None) -> bool:
    """Connect this process to Ray at `address` unless it already is; True if it connected (and
    so should disconnect, or stop the private instance of "local", when done)."""
    if ray.is_initialized():
        return False
    options = {"logging_level": logging.WARNING, "log_to_driver": False, "include_dashboard": False,
               **(init_options or {})}
    if address not in ("auto", "local"):
        check_reachable(address)
    try:
        if address == "local":
            notice = logging.getLogger(RAY_AUTH_LOGGER)
            quiet = _DefaultAuthNotice()
            notice.addFilter(quiet)
            try:
                ray.init(num_cpus=options.pop("num_cpus", os.cpu_count() or 1), **options)
            finally:
                notice.removeFilter(quiet)
        else:
            options.pop("include_dashboard")  # a setting of the cluster's head, not of a driver
            ray.init(address=address, **options)
    except (ConnectionError, RuntimeError, ValueError) as exc:
        text = str(exc).strip().splitlines()
        raise TwinError(f"--ray {address}: cannot connect ({text[0] if text else type(exc).__name__}); start a "
                        "cluster with `ray start --head` or use --ray local") from None
    return True


def check_reachable(address: str, timeout_s: float = 5.0) -> None:
    """TwinError unless something listens at HOST:PORT of the address: Ray itself retries an
    unreachable head for minutes (ray://) to a quarter of an hour (HOST:PORT) before it gives up."""
    host, sep, port = address.removeprefix("ray://").rpartition(":")
    if not sep or not host or not port.isdigit():
        raise TwinError(f"--ray {address}: expected auto, local, ray://HOST:PORT or HOST:PORT")
    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=timeout_s) as sock:
            grpc = _answers_http2(sock)
    except OSError as exc:
        raise TwinError(f"--ray {address}: nothing answers there ({exc.strerror or exc}); is the head running "
                        "(`ray start --head`) and its port open?") from None
    if not grpc:  # Ray would retry it for minutes, its own log lines on the terminal
        raise TwinError(f"--ray {address}: something answers there, but not Ray (no gRPC: a Ray head's port, "
                        "6379 by default, or its client's, ray://HOST:10001, speaks it)")


# a client's connection preface and an empty SETTINGS frame [RFC-7540 §3.5, §6.5]
HTTP2_PREFACE = b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n" + bytes([0, 0, 0, 4, 0, 0, 0, 0, 0])


def _answers_http2(sock: socket.socket) -> bool:
    """Whether the server on `sock` answers an HTTP/2 preface with its own, a SETTINGS frame (type 4)
    first [RFC-7540 §3.5]: Ray's head (GCS) and Ray Client are gRPC servers, which do."""
    sock.sendall(HTTP2_PREFACE)
    head = b""
    while len(head) < 9:
        part = sock.recv(9 - len(head))
        if not part:
            break
        head += part
    return len(head) == 9 and head[3] == 4


def check_auto_cluster() -> None:
    """TwinError unless --ray auto has a cluster to join, as Ray finds it [Ray-init]: the address in
    RAY_ADDRESS, else the one `ray start --head` leaves in ray_current_cluster under Ray's temporary
    folder (RAY_TMPDIR, TMPDIR, /tmp); checked before any work, which a command would otherwise do
    in full before Ray says there is none."""
    address = os.environ.get("RAY_ADDRESS", "").strip()
    if not address:
        folder = Path(os.environ.get("RAY_TMPDIR") or os.environ.get("TMPDIR") or "/tmp") / "ray"
        try:
            address = (folder / "ray_current_cluster").read_text().strip()
        except OSError:
            raise TwinError(f"--ray auto: no Ray cluster runs on this machine (no RAY_ADDRESS, no "
                            f"{folder / 'ray_current_cluster'}); start one with `ray start --head`, or use "
                            "--ray local") from None
    if address not in ("auto", "local"):
        check_reachable(address)


def cluster_cpus(ray) -> int:
    return max(1, int(math.floor(ray.cluster_resources().get("CPU", 1))))


def executor_from(ray: str | None, *, cpus_per_task: int = 1, retries: int = 3,
                  nthread: int | None = None) -> Executor:
    """The executor a command's --ray option names: None → local (every core of this machine). The
    cluster's options are checked either way: a bad value is refused, not ignored for want of --ray."""
    if cpus_per_task < 1:
        raise TwinError(f"--cpus-per-task must be at least 1, got {cpus_per_task}")
    if retries < 0:
        raise TwinError(f"--retries must be at least 0, got {retries}")
    if ray is None:
        return LocalExecutor(nthread)
    if not ray.strip():
        raise TwinError("--ray needs auto, local or an address (ray://HOST:10001 or HOST:6379)")
    if ray.strip() not in ("auto", "local"):
        check_reachable(ray.strip())  # before any work is done
    if ray.strip() == "auto":
        check_auto_cluster()
    return RayExecutor(ray.strip(), cpus_per_task=cpus_per_task, max_retries=retries)

