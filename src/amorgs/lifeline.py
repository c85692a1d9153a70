"""A workflow job dies with its workflow: no job (and so no solver worker) outlives a killed Snakemake.

Snakemake starts each job as a shell that starts ``python -m amorgs step``; if Snakemake itself is killed
outright (``kill -9`` of its process, an OOM kill), that shell and the job are re-parented to init and would
run on, finish, and close their MLflow runs FINISHED while the rerun solves the same job again.  So the
Snakefile names its own process in the environment its jobs inherit (:func:`mark_workflow`: host, pid and
the process's start time, which tells a reused pid apart), and every job watches that process
(:func:`watch_workflow`): once it is gone the job gets SIGTERM, which closes its MLflow run KILLED and stops
its solver pool (:mod:`amorgs.solvers.multistart`; the workers also die with the job by
``PR_SET_PDEATHSIG``); a job that has not ended :data:`GRACE_S` seconds later is killed outright.

Jobs on another host (SLURM nodes) watch the Snakemake that runs them there, which names itself in turn.
Linux reads the start time from ``/proc``; elsewhere the pid alone is watched.
"""

from __future__ import annotations

import os
import signal
import socket
import threading
import time
from pathlib import Path

#: The environment variable naming the workflow process: ``host:pid:start-time``.
ENV = "AMORGS_WORKFLOW"
#: Seconds between two looks at the workflow process.
INTERVAL_S = 1.0
#: Seconds a job has, after SIGTERM, to close its run before it is killed.
GRACE_S = 30.0


def _start_time(pid: int) -> str | None:
    """The start time of process ``pid`` (clock ticks since boot, from ``/proc``), "" where ``/proc`` is
    absent but the process exists, None if there is no such process."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except FileNotFoundError:
        if Path("/proc/self/stat").exists():
            return None
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return None
        except PermissionError:
            pass
        return ""
    except OSError:
        return None
    return stat.rsplit(")", 1)[1].split()[19]  # field 22; the command name before ")" may hold spaces


def _token(pid: int) -> str | None:
    start = _start_time(pid)
    return None if start is None else f"{socket.gethostname()}:{pid}:{start}"


def _alive(token: str) -> bool:
    host, pid, start = token.rsplit(":", 2)
    return host != socket.gethostname() or _token(int(pid)) == token


def mark_workflow(environ: dict = os.environ) -> str:
    """In the Snakefile: name this process as the workflow its jobs live by (``environ[ENV]``), unless a live
    workflow on this host already does (a Snakemake started inside a job keeps its outer one).  Returns it."""
    current = environ.get(ENV)
    if current and current.split(":", 1)[0] == socket.gethostname() and _alive(current):
        return current
    environ[ENV] = _token(os.getpid()) or ""
    return environ[ENV]


def workflow_gone(token: str) -> bool:
    """Whether the workflow process ``token`` (see :func:`mark_workflow`) on this host has ended."""
    return bool(token) and not _alive(token)


def watch_workflow(environ: dict = os.environ, interval_s: float = INTERVAL_S, grace_s: float = GRACE_S) -> bool:
    """In a job: end this process when the workflow named in ``environ[ENV]`` ends, or at once if it already
    has (module docstring).  A daemon thread looks every ``interval_s``; returns whether there is a workflow
    on this host to watch."""
    token = environ.get(ENV, "")
    if not token or token.split(":", 1)[0] != socket.gethostname():
        return False  # no workflow (a job run by hand), or one on another host

    def watch() -> None:
        while not workflow_gone(token):
            time.sleep(interval_s)
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(grace_s)
        os.kill(os.getpid(), signal.SIGKILL)

    threading.Thread(target=watch, name="amorgs-lifeline", daemon=True).start()
    return True
