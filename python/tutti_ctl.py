"""Control a running tutti co-simulation from Python: the calls of `tutti ctl`.

    import tutti_ctl
    run = tutti_ctl.connect()            # the run of TUTTI_NAMESPACE (default: tutti)
    run.pause()
    print(run.step(7))                   # exactly 7 steps, then paused again
    run.reset()                          # step count and simulated time back to zero
    run.resume()
    run.restart("ctrl")                  # a component of a `tutti run`
    run.signal("uav3", "USR1")           # a signal to a component's process
    run.stop()

Every call returns the run's state after it, a dict: {"state": "paused", "step": 7,
"sim_time": 0.07, "namespace": ..., "pid": ..., "components": [...]}. A command the run
refuses raises ControlError with its reason; no run in the namespace raises NoRun.

The run listens on a Unix socket beside its segments (/dev/shm/tutti-ctl.<namespace>),
one JSON object per line each way; only the user who started it may connect. docs/run.md
describes the protocol. Standard library only.
"""

import json
import os
import socket
import struct

__all__ = ["ControlError", "NoRun", "Run", "connect", "socket_path"]


class ControlError(Exception):
    """The run refused a command (the message says why) or answered something unexpected."""


class NoRun(ControlError):
    """No run serves the namespace."""


def socket_path(namespace=None):
    """Where the control socket of `namespace` (default: TUTTI_NAMESPACE, else tutti) is."""
    ns = namespace or os.environ.get("TUTTI_NAMESPACE") or "tutti"
    return "/dev/shm/tutti-ctl." + ns


class Run:
    """A connection to a run's control plane."""

    def __init__(self, namespace=None, timeout=30.0):
        self.path = socket_path(namespace)
        self._sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self._sock.settimeout(timeout)
        try:
            self._sock.connect(self.path)
        except (FileNotFoundError, ConnectionRefusedError) as e:
            self._sock.close()
            raise NoRun("no run in namespace %r (no control socket %s)" % (namespace, self.path)) from e
        # The socket directory is everyone's: a socket of this name that another user made is
        # not this user's run, and is told nothing.
        creds = self._sock.getsockopt(socket.SOL_SOCKET, socket.SO_PEERCRED, struct.calcsize("3i"))
        uid = struct.unpack("3i", creds)[1]
        if uid != os.getuid():
            self._sock.close()
            raise ControlError("the control socket %s of namespace %r is served by another user (uid %d), not by a run "
                               "of yours" % (self.path, self.path.split("tutti-ctl.", 1)[1], uid))
        self._file = self._sock.makefile("rb")

    def close(self):
        self._file.close()
        self._sock.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def request(self, op, **args):
        """Sends {"op": op, **args}; returns the run's state, or raises ControlError."""
        self._sock.sendall((json.dumps(dict(op=op, **args)) + "\n").encode())
        line = self._file.readline()
        if not line:
            raise ControlError("the run closed the connection")
        answer = json.loads(line)
        if not answer.get("ok"):
            raise ControlError(answer.get("error", "refused"))
        return answer["status"]

    def state(self):
        return self.request("state")

    def pause(self):
        return self.request("pause")

    def resume(self):
        return self.request("resume")

    def step(self, n):
        """While paused: exactly n steps, then paused again (answers when they are made)."""
        return self.request("step", n=int(n))

    def reset(self):
        return self.request("reset")

    def stop(self):
        """Ends the run (a `tutti run` tears its components down)."""
        return self.request("stop")

    def restart(self, component):
        return self.request("component", action="restart", name=component)

    def stop_component(self, component):
        return self.request("component", action="stop", name=component)

    def start_component(self, component):
        return self.request("component", action="start", name=component)

    def signal(self, component, sig):
        """Sends signal `sig` ("USR1", "SIGUSR2", "TERM", ...) to a running component's process."""
        return self.request("signal", name=component, signal=str(sig))


def connect(namespace=None, timeout=30.0):
    """A connection to the run of `namespace` (default: TUTTI_NAMESPACE, else tutti)."""
    return Run(namespace, timeout)
