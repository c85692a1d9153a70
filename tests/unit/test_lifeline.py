"""amorgs.lifeline: a job ends when the workflow process that started it is gone (real processes, real kill -9)."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from amorgs import lifeline

pytestmark = pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="Linux /proc")

#: A stand-in job: it records a SIGTERM (as a tracked job closes its run KILLED) and exits; else sleeps.
JOB = """
import signal, sys, time
from amorgs import lifeline
def term(*_):
    open(sys.argv[1], "w").write("SIGTERM")
    sys.exit(143)
signal.signal(signal.SIGTERM, term)
print(lifeline.watch_workflow(interval_s=0.1), flush=True)
time.sleep(600)
"""

#: A stand-in workflow: it names itself, starts the job and waits.
WORKFLOW = """
import subprocess, sys, time
from amorgs import lifeline
lifeline.mark_workflow()
job = subprocess.Popen([sys.executable, "-c", sys.argv[1], sys.argv[2]])
print(job.pid, flush=True)
time.sleep(600)
"""


def _gone(pid: int, timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
        except FileNotFoundError:
            return True
        if state == "Z":
            return True
        time.sleep(0.1)
    return False


def test_a_job_ends_with_sigterm_when_its_workflow_is_killed_9(tmp_path):
    mark = tmp_path / "job.txt"
    env = {k: v for k, v in os.environ.items() if k != lifeline.ENV}
    wf = subprocess.Popen([sys.executable, "-c", WORKFLOW, JOB, str(mark)], stdout=subprocess.PIPE, text=True, env=env)
    job = int(wf.stdout.readline())
    try:
        time.sleep(1.0)
        assert not _gone(job, 0.5), "the job ended while its workflow was alive"
        wf.kill()  # kill -9: the workflow cannot tell its job anything
        wf.wait()
        assert _gone(job, 15), "the job outlived its killed workflow"
        assert mark.read_text() == "SIGTERM"  # it was asked to stop first, so it could close its run
    finally:
        if not _gone(job, 0):
            os.kill(job, signal.SIGKILL)


def test_marks_keep_a_live_outer_workflow_and_other_hosts_are_not_watched(tmp_path):
    env: dict[str, str] = {}
    token = lifeline.mark_workflow(env)
    assert token == env[lifeline.ENV] and token.startswith(f"{socket.gethostname()}:{os.getpid()}:")
    outer = {lifeline.ENV: token}
    assert lifeline.mark_workflow(outer) == token  # a live workflow on this host keeps its name
    stale = {lifeline.ENV: f"{socket.gethostname()}:999999999:1"}
    assert lifeline.mark_workflow(stale) == token  # a dead one is replaced
    assert lifeline.workflow_gone(f"{socket.gethostname()}:999999999:1")
    assert lifeline.workflow_gone(token.rsplit(":", 1)[0] + ":0")  # same pid, other start time: a reused pid
    assert not lifeline.workflow_gone(token)
    assert not lifeline.watch_workflow({lifeline.ENV: "some-slurm-submit-host:1:1"})  # another host's workflow
    assert not lifeline.watch_workflow({})  # a job run by hand
