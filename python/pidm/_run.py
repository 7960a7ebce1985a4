"""Running scenes with the pidm binary: pidm.run and pidm.check."""

from __future__ import annotations

import contextlib
import json
import os
import queue
import shutil
import signal
import subprocess
import tempfile
import threading
import warnings
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from ._binary import describe_exit, error_text, find_binary, run_quiet
from ._errors import PidmError, SceneError
from ._read import open as open_result
from ._toml import dumps

#: A scene: a path to a TOML file, TOML text, or a dict shaped like the TOML.
Scene = str | os.PathLike | Mapping[str, Any]

#: What progress=... takes: True (a tqdm bar when tqdm is installed), False (none),
#: or a function called with every progress record (a dict).
ProgressArg = bool | Callable[[dict[str, Any]], None]

#: Seconds a stopped child gets to end by itself after SIGINT before SIGKILL.
STOP_GRACE_S = 2.0


class RunWarning(UserWarning):
    """A run finished but some instances did not finish normally (exit status 3):
    their map entries are 0 and ``status`` says why."""


@contextlib.contextmanager
def _scene_file(scene: Scene, workdir: Path) -> Iterator[str]:
    """The scene as a file pidm can read: a given path as it is, text or a dict
    written to ``workdir/scene.toml`` (so a scene without ``name`` is named
    ``scene``)."""
    if isinstance(scene, Mapping):
        text = dumps(scene)
    elif isinstance(scene, os.PathLike):
        path = Path(scene)
        if not path.is_file():
            raise FileNotFoundError(f"no scene file {os.fspath(scene)}")
        yield os.fspath(path)
        return
    elif isinstance(scene, str):
        if "\n" not in scene and Path(scene).is_file():
            yield scene
            return
        if "=" not in scene and "[" not in scene and "\n" not in scene and scene.strip():
            raise FileNotFoundError(
                f"no scene file {scene!r} (TOML text would have a `key = value` line)"
            )
        text = scene
    else:
        raise TypeError(f"a scene is a path, TOML text or a dict, not {type(scene).__name__}")
    path = workdir / "scene.toml"
    path.write_text(text, encoding="utf-8")
    yield os.fspath(path)


def _option_args(options: Mapping[str, Any]) -> list[str]:
    """``pidm run`` flags from keyword options: ``chunk_size=100`` is
    ``--chunk-size 100``, ``verify=True`` is ``--verify``; False and None are left
    out."""
    args: list[str] = []
    for key, value in options.items():
        flag = "--" + key.replace("_", "-")
        if value is None or value is False:
            continue
        if value is True:
            args.append(flag)
        else:
            args += [flag, str(value)]
    return args


def check(scene: Scene) -> dict[str, Any]:
    """Validates a scene without running it (``pidm check --json``).

    Returns a dict with ``name``, ``layout`` (``"grid"`` or ``"points"``), ``axes``
    (per grid axis: ``key``, ``units``, ``size``, ``first``, ``last``),
    ``instances``, ``shape``, ``labels``, ``baselines``, ``trajectories`` (how
    many), ``output_bytes``, ``integrations`` (distinct, baselines included), and
    the cost estimate: ``simulated_s`` [simulated s, baselines included, to every
    ``max_cycles`` when steady], ``core_seconds`` [s of one core], ``estimate_s``
    [wall s on the CPU path, ``estimate_backend``, on this machine's ``cores``; of
    it ``estimate_sweep_s`` integrating and ``estimate_trajectories_s`` recording
    trajectories],
    measured by a short probe of a few instances (``probe``: ``integrations``,
    ``scaled``, ``cut``, ``mean_periods``, ``mean_core_s``, ``wall_s``,
    ``parallelism``); ``estimate_is_upper_bound`` when a probed steady instance
    was charged up to its ``max_cycles``. Raises SceneError (a ValueError) with
    pidm's message for a scene pidm refuses.
    """
    binary = find_binary()
    with (
        tempfile.TemporaryDirectory(prefix="pidm-") as tmp,
        _scene_file(scene, Path(tmp)) as path,
    ):
        command = [binary, "check", "--json", path]
        done = run_quiet(command)
    if done.returncode == 1:
        raise SceneError(error_text(done.stderr), stderr=done.stderr, returncode=1, command=command)
    if done.returncode != 0:
        raise PidmError(
            f"{describe_exit(done.returncode)}: {error_text(done.stderr)}",
            stderr=done.stderr,
            returncode=done.returncode,
            command=command,
        )
    return json.loads(done.stdout)


def run(
    scene: Scene,
    *,
    backend: str = "auto",
    precision: str | None = None,
    threads: int | None = None,
    out: str | os.PathLike[str] | None = None,
    progress: ProgressArg = True,
    **options: Any,
) -> xr.Dataset:
    """Runs a scene with the pidm binary and returns its maps as an xarray Dataset.

    Parameters
    ----------
    scene
        A path to a scene file, TOML text, or a dict shaped like the TOML, e.g.
        ``{"axis": {"x": {"voltage": {"from": 0, "to": 150, "steps": 31}}}}``
        (voltages in V, frequencies in Hz, masses in kg, ...; docs/scenes.md lists
        every key). Dict keys keep their order, which is the grid's axis order; a
        key with dots (``"axis.y.voltage"``) is a dotted TOML key. A dict or text
        without ``name`` is named ``"scene"``.
    backend
        ``"auto"`` (a hardware GPU with f64 when the run is large enough, else the
        CPU), ``"gpu"`` or ``"cpu"``.
    precision
        ``"f32"`` or ``"f64"`` [default: f64 where the adapter has it, f64 on the
        CPU]. With ``backend="cpu"``, ``"f32"`` runs the f32 shader's CPU mirror.
    threads
        Worker threads of the CPU path [default: every core].
    out
        Where to keep the result file (HDF5). None writes it to a temporary folder
        that is removed once the Dataset is read.
    progress
        True shows a tqdm bar (``tqdm.auto``, so also in notebooks) when tqdm is
        installed, and nothing otherwise; False shows nothing; a function is called
        with every progress record: a dict with ``done``, ``total`` (instances; a
        scene with ``[stall]`` counts each twice, its unloaded run and its search),
        ``elapsed_s`` [s], ``eta_s`` [s, None before the first instance finished]
        and ``instances_per_s``.
    **options
        Other ``pidm run`` flags, underscores for dashes: ``verify=True``,
        ``chunk_size=1000``, ``shard="1/4"``, ``resume=True``.

    Returns
    -------
    xarray.Dataset
        Loaded in memory (see :func:`pidm.open`): the grid axes as dimensions and
        coordinates with ``units``, every map as a data variable (``step_x``,
        ``step_y`` [m per own drive cycle], ``velocity_x``, ``velocity_y`` [m/s],
        ``status``, ``steps``, ``motion`` (uint8 kind of motion with CF
        ``flag_values`` and ``flag_meanings``), ``baseline_*``, with ``[output] backward``
        ``backward_x`` [m per own drive cycle] and ``backward_ratio_x`` with their
        ``_se`` (and ``_y``), and for a scene with
        ``[stall]`` the stall maps ``stall_load_x`` [N], ``stall_step_near_x``,
        ``stall_step_far_x`` [m per own drive cycle], ``stall_waves_x`` and
        ``stall_status_x`` (or ``_y``), ...), the scene and run facts as attributes. A run where some instances did not finish normally warns
        (RunWarning); mask the maps with ``status == 0``.

    Raises
    ------
    SceneError
        pidm refuses the scene (a ValueError; the message names the key).
    PidmError
        Any other failure, with pidm's error text; also when there is no binary
        (``PIDM_BINARY``, else ``pidm`` on ``PATH``).
    KeyboardInterrupt
        On Ctrl-C the run is stopped at once (SIGINT, then SIGKILL after
        ``STOP_GRACE_S`` seconds), no pidm process stays, nothing is left at
        ``out`` (a given ``out`` keeps pidm's checkpoint beside it, so
        ``resume=True`` continues), and the interrupt is raised again.
    """
    _check_backend(backend)
    if precision not in (None, "f32", "f64"):
        raise ValueError(f"precision={precision!r}: expected None, 'f32' or 'f64'")
    _check_threads(threads)
    binary = find_binary()
    workdir = Path(tempfile.mkdtemp(prefix="pidm-"))
    try:
        result = workdir / "result.h5" if out is None else Path(out).absolute()
        existed = result.exists()
        with _scene_file(scene, workdir) as scene_path:
            command = [binary, "run", scene_path, "--out", os.fspath(result)]
            command += ["--backend", backend]
            if precision is not None:
                command += ["--precision", precision]
            if threads is not None:
                command += ["--threads", str(int(threads))]
            command += ["--progress", "none" if progress is False else "jsonl"]
            command += _option_args(options)
            try:
                returncode, stderr = _watch(command, progress)
            except KeyboardInterrupt as interrupt:
                if out is not None:
                    _after_interrupt(result, existed, interrupt)
                raise
            if returncode == 1:
                # A scene pidm refuses fails `pidm check` too; anything else is
                # the run's own failure.
                checked = run_quiet([binary, "check", scene_path])
                if checked.returncode == 1:
                    raise SceneError(
                        error_text(checked.stderr),
                        stderr=checked.stderr,
                        returncode=1,
                        command=command,
                    )
            if returncode not in (0, 3):
                message = error_text(stderr)
                if returncode != 1:
                    message = f"{describe_exit(returncode)}: {message}"
                raise PidmError(message, stderr=stderr, returncode=returncode, command=command)
            if returncode == 3:
                warnings.warn(
                    "pidm: some instances did not finish normally; their map entries are 0 "
                    "and the status map says why",
                    RunWarning,
                    stacklevel=2,
                )
            return open_result(result)
    finally:
        shutil.rmtree(workdir, ignore_errors=True)


def _check_backend(backend: str) -> None:
    if backend not in ("auto", "cpu", "gpu"):
        raise ValueError(f"backend={backend!r}: expected 'auto', 'cpu' or 'gpu'")


def _check_threads(threads: int | None) -> None:
    if threads is not None and (
        isinstance(threads, bool) or int(threads) != threads or threads < 1
    ):
        raise ValueError(f"threads={threads!r}: expected a whole number of at least 1")


def _check_search(
    backend: str, threads: int | None, seed: object, out: object, beside: str
) -> None:
    """The arguments every search takes (``pidm.fit``, ``pidm.optimize``,
    ``pidm.sensitivity``): ``backend``, ``threads``, a ``seed`` of at least 0, and
    an ``out`` that is a .json file (``beside``: what is written beside it)."""
    _check_backend(backend)
    _check_threads(threads)
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed={seed!r}: expected a whole number of at least 0")
    if out is not None and Path(out).suffix != ".json":
        raise ValueError(
            f"out={os.fspath(out)!r}: expected a .json file ({beside} written beside it)"
        )


def _after_interrupt(result: Path, existed: bool, interrupt: BaseException) -> None:
    """A run interrupted from Python leaves nothing at ``out``: a file that a run
    finished in the same moment is removed (when there was none before)."""
    if result.exists() and not existed:
        with contextlib.suppress(OSError):
            result.unlink()
    checkpoint = result.with_name(f".{result.name}.checkpoint")
    if checkpoint.exists() and hasattr(interrupt, "add_note"):
        interrupt.add_note(
            f"pidm: the finished instances are kept in {checkpoint}; "
            "the same pidm.run(..., resume=True) continues the run"
        )


def _is_run_record(record: Any) -> bool:
    """Whether a JSON line of stderr is a progress record of ``pidm run``."""
    return isinstance(record, dict) and "done" in record and "total" in record


def _watch(
    command: list[str],
    progress: ProgressArg,
    *,
    is_record: Callable[[Any], bool] = _is_run_record,
    shower: type[_Shower] | None = None,
) -> tuple[int, str]:
    """Runs pidm, shows its JSON progress lines (those ``is_record`` takes, with a
    ``shower``, by default ``pidm run``'s bar), and returns its exit status and
    the rest of its stderr. On Ctrl-C (or any exception) stops it (SIGINT, then
    SIGKILL) and raises KeyboardInterrupt (the exception)."""
    # Set by Ctrl-C: a plain flag, which a signal handler may set safely.
    interrupted = _Flag()
    # Set when pidm closes its stderr (it ends), by the reader thread.
    wake = threading.Event()
    with _sigint_as_flag(interrupted):
        child = subprocess.Popen(
            command,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            errors="replace",
            bufsize=1,
        )
        records: queue.Queue[dict[str, Any]] = queue.Queue()
        text: list[str] = []

        def read_stderr() -> None:
            assert child.stderr is not None
            try:
                for line in child.stderr:
                    if line.startswith("{"):
                        try:
                            record = json.loads(line)
                        except ValueError:
                            record = None
                        if is_record(record):
                            records.put(record)
                            continue
                    text.append(line)
            finally:
                wake.set()

        def read_stdout() -> None:
            assert child.stdout is not None
            for _ in child.stdout:
                pass

        readers = [
            threading.Thread(target=read_stderr, daemon=True),
            threading.Thread(target=read_stdout, daemon=True),
        ]
        show = (shower or _Shower)(progress)
        try:
            for reader in readers:
                reader.start()
            while True:
                if interrupted.is_set:
                    raise KeyboardInterrupt
                returncode = child.poll()
                show.drain(records)
                if returncode is not None:
                    break
                if wake.wait(0.1) and not interrupted.is_set:
                    # stderr closed: pidm is ending; poll until it has.
                    child.wait()
            for reader in readers:
                reader.join()
            show.drain(records)
        except BaseException:
            _stop(child)
            for reader in readers:
                if reader.is_alive() or reader.ident is not None:
                    reader.join(timeout=1.0)
            raise
        finally:
            show.close()
    return returncode, "".join(text)


class _Flag:
    """A flag that a signal handler may set. Not a ``threading.Event``: its
    ``set`` takes a lock that the interrupted code (an ``Event.wait`` in the same
    thread) may hold, and the handler would then wait for it forever."""

    def __init__(self) -> None:
        self.is_set = False


@contextlib.contextmanager
def _sigint_as_flag(flag: _Flag) -> Iterator[None]:
    """While a run is watched, SIGINT (Ctrl-C) only sets a flag, so the watching
    loop (which looks at it every 0.1 s) stops the child and raises
    KeyboardInterrupt itself, never from inside subprocess's bookkeeping. Only in
    the main thread, and only where SIGINT raises KeyboardInterrupt (Python's
    default handler); otherwise SIGINT is left as it is."""

    def on_sigint(_signum: int, _frame: Any) -> None:
        flag.is_set = True

    previous = None
    if (
        threading.current_thread() is threading.main_thread()
        and signal.getsignal(signal.SIGINT) is signal.default_int_handler
    ):
        previous = signal.signal(signal.SIGINT, on_sigint)
    try:
        yield
    finally:
        if previous is not None:
            signal.signal(signal.SIGINT, previous)


def _stop(child: subprocess.Popen) -> None:
    """Ends the child: SIGINT (it keeps its checkpoint), SIGKILL after a grace."""
    if child.poll() is not None:
        return
    try:
        child.send_signal(signal.SIGINT)
        child.wait(timeout=STOP_GRACE_S)
    except (subprocess.TimeoutExpired, KeyboardInterrupt):
        # The grace ran out, or a second Ctrl-C: no more waiting.
        child.kill()
        child.wait()


class _Shower:
    """Shows progress records: a tqdm bar, a function, or nothing. ``bar``
    draws ``pidm run``'s bar (instances done of the total); a subclass draws
    another command's."""

    def __init__(self, progress: ProgressArg) -> None:
        self.callback: Callable[[dict[str, Any]], None] | None = None
        self.tqdm: Any = None
        self.bar: Any = None
        if callable(progress):
            self.callback = progress
        elif progress:
            try:
                from tqdm.auto import tqdm
            except ImportError:
                tqdm = None
            self.tqdm = tqdm

    def drain(self, records: queue.Queue[dict[str, Any]]) -> None:
        while True:
            try:
                record = records.get_nowait()
            except queue.Empty:
                return
            if self.callback is not None:
                self.callback(record)
            elif self.tqdm is not None:
                self.show(record)

    def show(self, record: dict[str, Any]) -> None:
        """Moves the tqdm bar (made at the first record) to ``record``."""
        if self.bar is None:
            self.bar = self.tqdm(
                total=int(record["total"]),
                initial=int(record["done"]),
                unit="instance",
                desc="pidm",
            )
        self.bar.update(int(record["done"]) - self.bar.n)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
