"""A sweep job on whatever machine its launcher chose: threads from what the launcher granted
the job, not from the machine that started the sweep (a SLURM login node or a Ray head may have
many more cores than a job got), and the sweep's folder as the working folder."""

from __future__ import annotations

import os
import signal
import socket
import sys
import threading
import time
from collections.abc import Mapping, Sequence
from typing import Any

from sigmarl.errors import SigmarlError

SWEEP_DIR = "SIGMARL_SWEEP_DIR"  # set by Hydra around each job of `sigmarl sweep`


def granted_threads(launcher: Mapping[str, Any], environ: Mapping[str, str] = os.environ,
                    ray_cpus: float | None = None, cores: int | None = None) -> int:
    """CPU threads for one job, first of: SLURM's grant (SLURM_CPUS_PER_TASK, set on a real
    cluster, also through submitit), the CPUs Ray assigned to this task, the launcher config's
    `cpus_per_task` (submitit's local executor, which sets no variable), the cores this process
    may run on divided among joblib's `n_jobs`."""
    if environ.get("SLURM_CPUS_PER_TASK"):
        return max(1, int(environ["SLURM_CPUS_PER_TASK"]))
    if ray_cpus:
        return max(1, int(ray_cpus))
    if launcher.get("cpus_per_task"):
        return int(launcher["cpus_per_task"])
    cores = cores or len(os.sched_getaffinity(0))
    return max(1, cores // int(launcher.get("n_jobs") or 1))


def job_threads(configured: int) -> int:
    """`threads` for the running Hydra job: the user's `threads=` override if given, else
    granted_threads from the job's launcher config and environment."""
    # lazy: the CLI imports this at start-up; Hydra only inside a sweep job
    from hydra.core.hydra_config import HydraConfig

    if SWEEP_DIR not in os.environ or not HydraConfig.initialized():  # not a sweep job
        return configured
    hydra = HydraConfig.get()
    if user_set("threads", hydra.overrides.task):
        return configured
    return granted_threads(hydra.launcher, ray_cpus=_ray_cpus())


def user_set(key: str, overrides: Sequence[str]) -> bool:
    return any(o.split("=", 1)[0].lstrip("+~") == key for o in overrides)


def _ray_cpus() -> float | None:
    """The CPUs Ray assigned to the current task; None outside a Ray worker."""
    if "ray" not in sys.modules:
        return None
    # optional: Ray only inside a Ray worker
    import ray

    if not ray.is_initialized():
        return None
    return ray.get_runtime_context().get_assigned_resources().get("CPU")


def sweep_folder_override() -> str:
    """The override that hands the sweep's folder to its jobs: Hydra sets the variable around
    each job wherever it runs. (Hydra's own runtime.cwd is composed in the job's process for
    joblib and submitit, so it names the worker's folder, not the sweep's.)"""
    folder = os.getcwd().replace("\\", "\\\\").replace("'", "\\'")
    return f"++hydra.job.env_set.{SWEEP_DIR}='{folder}'"


def enter_sweep_folder() -> None:
    """Inside a sweep job, work in the folder the sweep was started from, so that relative run
    folders and stores mean the same on every node (Ray workers and reused joblib workers
    start elsewhere). Needs that folder on a shared filesystem."""
    if folder := os.environ.get(SWEEP_DIR):
        os.chdir(folder)


SWEEP_OWNER = "SIGMARL_SWEEP_OWNER"  # "<pid> <host>" of the `sigmarl sweep` process
OWNER_POLL_S = 2.0


def sweep_owner_override() -> list[str]:
    """Hands the sweep's process id and host to its jobs (see `end_with_the_sweep`)."""
    return [f"++hydra.job.env_set.{SWEEP_OWNER}='{os.getpid()} {socket.gethostname()}'"]


def end_with_the_sweep() -> None:
    """In a job running on the sweep's own machine in another process (joblib's workers), end
    the job as interrupted (SIGTERM to itself: checkpoint-safe, resumable) once the sweep's
    process is gone, so a sweep killed with kill -9 leaves no worker training on behind it.
    A job on another machine (SLURM, Ray) lives by its scheduler's rules instead."""
    owner = os.environ.get(SWEEP_OWNER, "").split()
    if len(owner) != 2 or owner[1] != socket.gethostname() or int(owner[0]) == os.getpid():
        return
    pid = int(owner[0])

    def watch() -> None:
        while True:
            time.sleep(OWNER_POLL_S)
            try:
                os.kill(pid, 0)
            except ProcessLookupError:
                os.kill(os.getpid(), signal.SIGTERM)
                return
            except PermissionError:  # alive, someone else's: not our sweep any more
                return

    if not any(t.name == "sigmarl-sweep-owner" for t in threading.enumerate()):
        threading.Thread(target=watch, name="sigmarl-sweep-owner", daemon=True).start()


def use_threads(threads: int) -> None:
    """torch's CPU threads for this process: every command that computes sets them here from
    its composed config (`threads`), right before its work (torch is imported only then)."""
    if threads < 1:
        raise SigmarlError(f"threads must be positive, got {threads}")
    check_threads(threads)
    # lazy: torch only right before the work (start-up)
    import torch

    torch.set_num_threads(threads)


THREADS_PER_CPU = 4  # beyond this, more threads only contend; far beyond it, they exhaust process ids


def check_threads(threads: int, cpus: int | None = None) -> None:
    """`threads` within a generous cap of the CPUs of the machine the work runs on (checked
    there, not where a sweep was submitted: a login node may have fewer cores than a job gets)."""
    cpus = cpus or os.cpu_count() or 1
    if threads > THREADS_PER_CPU * cpus:
        raise SigmarlError(f"threads={threads} is more than {THREADS_PER_CPU} x the {cpus} CPUs of this machine "
                           f"({socket.gethostname()}); use threads={cpus} or fewer")
