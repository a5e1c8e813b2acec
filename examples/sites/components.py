"""The components of the two-site example (README.md here): `cart` on the home site, and
`operator` and `controller` on the other site. Each is this file with its name:

    python3 components.py cart          # home: a cart (1 kg, viscous friction), pushed by `force`
    python3 components.py operator      # away: sets the cart's target position
    python3 components.py controller    # away: answers each step of `link` with a force

They speak the RTAPI through the Python binding (python/tutti_rtapi.py; PYTHONPATH set by the
launch files) and end when their framework does.
"""

import sys
import time

import tutti_rtapi as rt

STEP = 0.010  # seconds of simulated time per step (home.json5's framework.step)
MASS, FRICTION = 1.0, 0.5  # kg, N s/m
KP, KD = 4.0, 3.0  # the controller's gains (N/m, N s/m)


def connect(domain, ddf, patience=60.0):
    """Connects to `domain`, waiting up to `patience` seconds for it to exist (the other
    site's mirror creates `link` once it has started)."""
    deadline = time.monotonic() + patience
    while True:
        try:
            return rt.connect(domain, timeout=10, ddf=ddf)
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
    position, velocity = 0.0, 0.0
    with connect("cart", "home.ddf") as conn:
        while True:
            (force,) = read(conn, "force")
            velocity += (force - FRICTION * velocity) / MASS * STEP
            position += velocity * STEP
            with conn.writing():
                conn.publish("position", position)
                conn.publish("velocity", velocity)


def operator():
    # The target: 1 m, then 0.5 m after 8 s.
    start = time.monotonic()
    with connect("target", "away.ddf") as conn:
        while True:
            with conn.writing():
                conn.publish("position_out", 1.0 if time.monotonic() - start < 8.0 else 0.5)
            time.sleep(0.05)


def controller():
    link = connect("link", "home.ddf")
    target = connect("target", "away.ddf")
    while True:
        position, velocity = read(link, "position", "velocity")
        (goal,) = read(target, "position")
        with link.writing():
            link.publish("force", KP * (goal - position) - KD * velocity)


if __name__ == "__main__":
    role = {"cart": cart, "operator": operator, "controller": controller}.get(sys.argv[1] if len(sys.argv) > 1 else "")
    if role is None:
        sys.exit("usage: components.py cart|operator|controller")
    try:
        role()
    except rt.RTAPIError as e:
        if not ended(e):
            raise
    except KeyboardInterrupt:
        pass
