"""The components of the two-site example (README.md here): `cart` on the home site, and
`operator` and `controller` on the other site. Each is this file with its name:

    python3 components.py cart          # home: a cart (1 kg, viscous friction), pushed by `force`
    python3 components.py operator      # away: sets the cart's target position
    python3 components.py controller    # away: answers each step of `link` with a force
    python3 components.py controller 1  # the same towards a fixed target (no operator)

The cart keeps its state for checkpoints (docs/run.md, "Checkpoints": `tutti ctl save` of the
home run); the controller has none (its force is a function of the step it answers).

They speak the RTAPI through the Python binding (python/tutti_rtapi.py; PYTHONPATH set by the
launch files) and end when their framework does.
"""

import struct
import sys
import time

import tutti_rtapi as rt

STEP = 0.010  # seconds of simulated time per step (home.json5's framework.step)
MASS, FRICTION = 1.0, 0.5  # kg, N s/m
KP, KD = 4.0, 3.0  # the controller's gains (N/m, N s/m)


def connect(domain, ddf, patience=60.0, state=None):
    """Connects to `domain`, waiting up to `patience` seconds for it to exist (the other
    site's mirror creates `link` once it has started); `state`: (save, restore)."""
    deadline = time.monotonic() + patience
    while True:
        try:
            return rt.connect(domain, timeout=10, ddf=ddf, state=state)
        except rt.RTAPIError as e:
            if e.name != "RTAPI_ERROR_DOMAIN_NOT_FOUND" or time.monotonic() > deadline:
                raise
            time.sleep(0.2)


def read(conn, *items):
    """The items of the next step: waits for it however long (the home run may start later)."""
    while True:
        try:
            with conn.reading():
                return [conn.subscribe(i) for i in items]
        except rt.RTAPIError as e:
            if e.name != "RTAPI_ERROR_TIMEOUT":
                raise


def ended(e):
    """Whether an RTAPI error means the framework has gone (the run is over)."""
    return e.name in ("RTAPI_ERROR_CONNECTION_LOST", "RTAPI_ERROR_NOT_CONNECTED", "RTAPI_ERROR_DOMAIN_NOT_FOUND")


def cart():
    s = [0.0, 0.0]  # position, velocity

    def restore(data):
        s[:] = struct.unpack("<2d", data)

    with connect("cart", "home.ddf", state=(lambda: struct.pack("<2d", *s), restore)) as conn:
        # The seed (the domain has states=yes): the state before the first step.
        with conn.writing():
            conn.publish("position", s[0])
            conn.publish("velocity", s[1])
        while True:
            (force,) = read(conn, "force")
            s[1] += (force - FRICTION * s[1]) / MASS * STEP
            s[0] += s[1] * STEP
            with conn.writing():
                conn.publish("position", s[0])
                conn.publish("velocity", s[1])


def operator():
    # The target: 1 m, then 0.5 m after 8 s.
    start = time.monotonic()
    with connect("target", "away.ddf") as conn:
        while True:
            with conn.writing():
                conn.publish("position_out", 1.0 if time.monotonic() - start < 8.0 else 0.5)
            time.sleep(0.05)


def controller(fixed=None):
    link = connect("link", "home.ddf")
    target = connect("target", "away.ddf") if fixed is None else None
    while True:
        position, velocity = read(link, "position", "velocity")
        (goal,) = read(target, "position") if target else (fixed,)
        with link.writing():
            link.publish("force", KP * (goal - position) - KD * velocity)


if __name__ == "__main__":
    role = {"cart": cart, "operator": operator, "controller": controller}.get(sys.argv[1] if len(sys.argv) > 1 else "")
    if role is None:
        sys.exit("usage: components.py cart|operator|controller")
    try:
        role(*[float(a) for a in sys.argv[2:3]])
    except rt.RTAPIError as e:
        if not ended(e):
            raise
    except KeyboardInterrupt:
        pass
