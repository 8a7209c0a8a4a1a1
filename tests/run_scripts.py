"""train.py and evaluate.py run as a user runs them, ``python SCRIPT ARGS``, for the tests of what a process does
(its exit status, its one line on stderr, a kill and a resume).

A fresh Python spends about 5 s importing torch, tensordict and TorchRL before the script's first line (Zen 4; about
twice that on a Zen 1), which these tests paid once per process. Here the process is forked from the test's own,
whose imports are done: the child runs the script from its top as ``__main__`` (its ``if __name__ == "__main__"``
block, its checks, Hydra), with its own argv, working directory, environment and output files, and ends with the
script's exit status, as the interpreter would end it. GNU OpenMP's threads do not survive a fork, so a process that
has run torch on more than one thread (a test run without ``-n``'s workers, which use one) starts a fresh Python
instead; so does one a test asks for (``fresh=True``) where what the interpreter does at start is what it tests.
"""

from __future__ import annotations

import os
import runpy
import signal
import subprocess
import sys
import tempfile
import time
import traceback
from dataclasses import dataclass
from pathlib import Path

import torch

ROOT = Path(__file__).resolve().parents[1]


@dataclass
class Finished:
    """What :func:`run` returns: as ``subprocess.run(..., capture_output=True, text=True)`` does."""

    returncode: int
    stdout: str
    stderr: str


class Script:
    """``python SCRIPT ARGS`` started, in ROOT, with ``env`` as its environment (this one's by default) and its
    stdout and stderr kept: ``poll``, ``wait``, ``send_signal`` and ``pid`` as a :class:`subprocess.Popen`'s."""

    def __init__(self, script: str, *args: str, env: dict[str, str] | None = None, fresh: bool = False):
        self._files = tempfile.TemporaryDirectory(prefix="waterair-script-")
        self._out, self._err = (Path(self._files.name) / name for name in ("stdout", "stderr"))
        self.returncode: int | None = None
        if fresh or torch.get_num_threads() > 1:
            with self._out.open("w") as out, self._err.open("w") as err:
                self._process: subprocess.Popen | None = subprocess.Popen(
                    [sys.executable, script, *args], cwd=ROOT, env=env, stdout=out, stderr=err, stdin=subprocess.DEVNULL
                )
            self.pid = self._process.pid
            return
        self._process = None
        sys.stdout.flush()
        sys.stderr.flush()
        self.pid = os.fork()
        if self.pid == 0:  # the child: never returns to the test
            os._exit(_run_script(script, list(args), env, self._out, self._err))

    def poll(self) -> int | None:
        if self.returncode is None:
            if self._process is not None:
                self.returncode = self._process.poll()
            else:
                pid, status = os.waitpid(self.pid, os.WNOHANG)
                if pid:
                    self.returncode = os.waitstatus_to_exitcode(status)
        return self.returncode

    def wait(self, timeout: float) -> int:
        deadline = time.monotonic() + timeout
        while self.poll() is None:
            if time.monotonic() > deadline:
                self.send_signal(signal.SIGKILL)
                self.wait(30)
                raise subprocess.TimeoutExpired(self.pid, timeout)
            time.sleep(0.05)
        return self.returncode  # type: ignore[return-value]

    def send_signal(self, sig: int) -> None:
        if self.poll() is None:
            os.kill(self.pid, sig)

    def output(self) -> Finished:
        """Its exit status and what it wrote, once it has ended."""
        assert self.returncode is not None, "the script is still running"
        finished = Finished(self.returncode, self._out.read_text(), self._err.read_text())
        self._files.cleanup()
        return finished


def run(script: str, *args: str, env: dict[str, str] | None = None, timeout: float = 300, fresh=False) -> Finished:
    """``python SCRIPT ARGS`` to its end (killed past ``timeout`` s): its exit status, stdout and stderr."""
    started = Script(script, *args, env=env, fresh=fresh)
    started.wait(timeout)
    return started.output()


def _run_script(script: str, args: list[str], env: dict[str, str] | None, out: Path, err: Path) -> int:
    """In the forked child: ``script`` run as ``python script args`` would run it; its exit status."""
    code = 1
    try:
        signal.signal(signal.SIGINT, signal.SIG_DFL)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        stdin = os.open(os.devnull, os.O_RDONLY)
        os.dup2(stdin, 0)
        for fd, path in ((1, out), (2, err)):
            os.dup2(os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC), fd)
        # the test's captured streams replaced by the process's own, line-buffered as on a console
        sys.stdin = open(0, closefd=False)  # noqa: SIM115
        sys.stdout = open(1, "w", buffering=1, closefd=False)  # noqa: SIM115
        sys.stderr = open(2, "w", buffering=1, closefd=False)  # noqa: SIM115
        import logging

        for handler in logging.root.handlers[:]:  # pytest's capturing handlers
            logging.root.removeHandler(handler)
        if env is not None:
            os.environ.clear()
            os.environ.update(env)
        os.chdir(ROOT)
        sys.argv = [script, *args]
        sys.path.insert(0, str(ROOT))  # the script's folder first, as python SCRIPT puts it
        try:
            runpy.run_path(str(ROOT / script), run_name="__main__")
            code = 0
        except SystemExit as stop:  # as the interpreter ends on it
            if stop.code is None or isinstance(stop.code, int):
                code = stop.code or 0
            else:
                print(stop.code, file=sys.stderr)
                code = 1
        except BaseException:
            traceback.print_exc()
            code = 1
        sys.stdout.flush()
        sys.stderr.flush()
    except BaseException:
        code = 1
    return code
