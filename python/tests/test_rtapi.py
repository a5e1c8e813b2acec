"""Tests of the Python RTAPI module against a live framework (the rtapi_test_host example of
crates/tutti-rtapi, built by `cargo test -p tutti-rtapi` or `cargo build -p tutti-rtapi --examples`).

    python3 -m unittest discover -s python/tests -v

Environment: TUTTI_RTAPI_LIB (librtapi.so), TUTTI_TEST_HOST (the host program); both default
to target/debug. Every test runs in its own TUTTI_NAMESPACE; the host is stopped (and its
segments removed) at the end even when a test fails, and it stops by itself after 60 s.
"""

import os
import struct
import subprocess
import sys
import tempfile
import threading
import time
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, "..", ".."))
sys.path.insert(0, os.path.join(ROOT, "python"))

import tutti_rtapi as rt  # noqa: E402

DDF = """<orchestra>
<domain name="pyasync"><synchronous>no</synchronous><multiplePublishAllowed>yes</multiplePublishAllowed><states>no</states>
  <set name="PUBLISH"><item name="x"><type>float64</type></item><item name="arr"><type>float64</type><length>3</length></item></set>
  <set name="SUBSCRIBE"><item name="a"><type>float64</type></item><item name="n"><type>int32</type></item>
    <item name="gps"><type>bus</type><item name="ok"><type>boolean</type></item><item name="v"><type>float32</type><length>2</length></item></item>
  </set>
</domain>
<domain name="pyevent"><synchronous>event</synchronous><multiplePublishAllowed>yes</multiplePublishAllowed><states>no</states>
  <set name="PUBLISH"><item name="x"><type>float64</type></item></set>
  <set name="SUBSCRIBE"><item name="a"><type>float64</type></item></set>
</domain>
<domain name="pysync"><synchronous>yes</synchronous><multiplePublishAllowed>no</multiplePublishAllowed><states>no</states>
  <set name="PUBLISH"><item name="x"><type>float64</type></item></set>
  <set name="SUBSCRIBE"><item name="a"><type>float64</type></item></set>
</domain>
</orchestra>
"""


def host_program():
    env = os.environ.get("TUTTI_TEST_HOST")
    if env:
        return env
    path = os.path.join(ROOT, "target", "debug", "examples", "rtapi_test_host")
    if not os.path.exists(path):
        subprocess.run(["cargo", "build", "-q", "-p", "tutti-rtapi", "--examples"], cwd=ROOT, check=True, timeout=600)
    return path


class Host:
    """The framework process: started with a fresh namespace, stopped by closing its stdin."""

    def __init__(self, test_name):
        self.dir = tempfile.TemporaryDirectory()
        self.ddf = os.path.join(self.dir.name, "py.ddf")
        with open(self.ddf, "w") as f:
            f.write(DDF)
        self.namespace = f"py{os.getpid()}-{test_name}"[:64]
        os.environ["TUTTI_NAMESPACE"] = self.namespace
        self.lines = []
        self.reader = None
        self.proc = subprocess.Popen(
            [host_program(), self.ddf, "2", "60", "--echo"],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
        )
        ready = self.proc.stdout.readline()
        if ready.strip() != "ready":
            self.stop()
            raise RuntimeError(f"host did not start: {ready!r}")
        self.reader = threading.Thread(target=self._read, daemon=True)
        self.reader.start()

    def _read(self):
        for line in self.proc.stdout:
            self.lines.append(line.split())

    def echoed(self, domain, item):
        """Values of `item` the framework read, per step: {step: value}."""
        out = {}
        for words in list(self.lines):
            if words and words[0] == domain:
                for kv in words[2:]:
                    k, _, v = kv.partition("=")
                    if k == item:
                        out[int(words[1])] = float(v)
        return out

    def send(self, line):
        """A command on the host's stdin (its checkpoint commands: `save`, `restore …`)."""
        self.proc.stdin.write(line + "\n")
        self.proc.stdin.flush()

    def answer(self, first):
        """The words of the host's last line starting with `first`, or None."""
        found = [w for w in list(self.lines) if w and w[0] == first]
        return found[-1] if found else None

    def stop(self):
        if self.proc.poll() is None:
            try:
                self.proc.stdin.close()
                self.proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
            if self.reader:
                self.reader.join(timeout=5)
            self.proc.stdout.close()
        self.dir.cleanup()


def wait_for(cond, limit=20.0):
    end = time.monotonic() + limit
    while time.monotonic() < end:
        if cond():
            return True
        time.sleep(0.01)
    return False


class RtapiTest(unittest.TestCase):
    def setUp(self):
        self.host = Host(self.id().rsplit(".", 1)[-1])
        self.addCleanup(self.host.stop)

    def test_async_typed_items_both_ways(self):
        with rt.connect("pyasync", timeout=5, ddf=self.host.ddf) as conn:
            self.assertEqual(conn.status, rt.STATUS_RUNNING)
            self.assertTrue(wait_for(lambda: conn.subscribe("x") > 0))
            x = conn.subscribe("x")
            arr = conn.subscribe("arr")
            self.assertEqual(len(arr), 3)
            self.assertGreaterEqual(arr[0], x)
            self.assertEqual(conn.item_key("x"), 0)
            self.assertEqual(conn.item_key("a"), 2)
            self.assertEqual(conn.item_info("gps/v"), (4, 2))
            conn.publish("a", 42.5)
            conn.publish("n", -7)
            conn.publish("gps/ok", True)
            conn.publish("gps/v", [1.5, -2.0])
            with conn.writing():
                conn.publish("a", 43.5)
            self.assertTrue(wait_for(lambda: 43.5 in self.host.echoed("pyasync", "a").values()))
            with conn.reading():
                self.assertGreater(conn.subscribe("x"), 0)

    def test_state_callbacks_hand_the_state_over_and_take_it_back(self):
        state = {"sum": 0.0, "broken": False}
        restored = []

        def save():
            if state["broken"]:
                raise RuntimeError("this state cannot be saved")
            return struct.pack("<d", state["sum"])

        def restore(data):
            state["sum"] = struct.unpack("<d", data)[0]
            restored.append(state["sum"])

        stop = threading.Event()
        with rt.connect("pysync", timeout=5, ddf=self.host.ddf, state=(save, restore)) as conn:

            def loop():
                # A step counter: the callbacks run in this thread, inside reading()'s wait.
                while not stop.is_set():
                    with conn.reading():
                        conn.subscribe("x")
                    state["sum"] += 1.0
                    with conn.writing():
                        conn.publish("a", state["sum"])

            t = threading.Thread(target=loop, daemon=True)
            t.start()
            try:
                self.assertTrue(wait_for(lambda: state["sum"] >= 5))
                self.host.send("save")
                self.assertTrue(wait_for(lambda: self.host.answer("saved")), self.host.lines[-3:])
                _, domain, name, data = self.host.answer("saved")
                self.assertEqual(domain, "pysync")
                self.assertGreaterEqual(struct.unpack("<d", bytes.fromhex(data))[0], 5.0)
                self.host.send(f"restore pysync {name} {struct.pack('<d', 1000.0).hex()}")
                self.assertTrue(wait_for(lambda: self.host.answer("restored")), self.host.answer("failed"))
                self.assertEqual(restored, [1000.0])
                # The next steps go on from the state taken back.
                self.assertTrue(wait_for(lambda: any(v > 1000 for v in self.host.echoed("pysync", "a").values())))
                # A save that raises fails the request, naming it; the run goes on.
                state["broken"] = True
                self.host.send("save")
                self.assertTrue(wait_for(lambda: self.host.answer("failed")))
                self.assertIn("save callback returned", " ".join(self.host.answer("failed")))
            finally:
                stop.set()
                t.join(timeout=20)

    def test_untyped_items_default_to_float64(self):
        with rt.connect("pyasync", timeout=5) as conn:
            conn.publish("a", 1.25)
            self.assertIsInstance(conn.subscribe("x"), float)
            conn.publish("gps/ok", 1)  # a 1-byte element is taken as uint8 without a DDF
            with self.assertRaises(ValueError):
                conn.publish("a", [1.0, 2.0])
            conn2 = rt.connect("pyasync", timeout=5, types={"gps/ok": "boolean"})
            conn2.publish("gps/ok", True)
            conn2.disconnect()

    def test_sync_lock_step(self):
        with rt.connect("pysync", timeout=5, ddf=self.host.ddf) as conn:
            seen = []
            for _ in range(30):
                with conn.reading():
                    x = conn.subscribe("x")
                with conn.writing():
                    conn.publish("a", x * 10)
                seen.append(x)
            # Every step read once, none skipped (after the first: see docs/rtapi.md).
            self.assertEqual(seen[1:], [seen[1] + i for i in range(29)])
            self.assertTrue(wait_for(lambda: int(seen[-1]) in self.host.echoed("pysync", "a")))
            echoed = self.host.echoed("pysync", "a")
            for x in seen[1:]:
                self.assertEqual(echoed[int(x)], x * 10)
            with self.assertRaises(rt.RTAPIError) as e:
                conn.subscribe("x")  # outside a lock pair in a synchronous domain
            self.assertEqual(e.exception.name, "RTAPI_ERROR_OUT_OF_ORDER")

    def test_event_driven_period_and_requested_times(self):
        # The host steps every 2 ms of simulated time, x holding the step number.
        with rt.connect("pyevent", timeout=5, ddf=self.host.ddf) as conn:
            conn.set_period(0.010)
            times, xs = [], []
            for _ in range(6):
                with conn.reading():
                    xs.append(conn.subscribe("x"))
                times.append(conn.simulation_time())
            # Due at its first step, then at the steps whose time is a multiple of 10 ms:
            # every fifth step.
            for t in times[1:]:
                self.assertAlmostEqual(t / 0.010, round(t / 0.010), places=6, msg=times)
            self.assertEqual([b - a for a, b in zip(xs[1:], xs[2:])], [5.0] * 4, xs)
            conn.set_period(0)
            conn.request_time(times[-1] + 0.007)  # 3.5 steps on: the 4th step
            with conn.reading():
                x = conn.subscribe("x")
            self.assertEqual(x - xs[-1], 4.0)
            with self.assertRaises(rt.RTAPIError) as e:
                conn.set_period(0.003)  # not a whole number of 2 ms steps
            self.assertEqual(e.exception.name, "RTAPI_ERROR_INVALID_ARGUMENT")
            self.assertIn("whole multiple", e.exception.detail)
            conn.set_wake_on_change(True)

    def test_connection_count_and_exclusive_writer(self):
        self.assertEqual(rt.connection_count("pysync"), 0)
        a = rt.connect("pysync", timeout=5)
        b = rt.connect("pysync", timeout=5)
        self.addCleanup(a.disconnect)
        self.addCleanup(b.disconnect)
        self.assertEqual(rt.connection_count("pysync"), 2)
        self.assertEqual(a.connection_count(), 2)
        with a.reading():
            pass
        with a.writing():
            pass
        with self.assertRaises(rt.RTAPIError) as e:
            b.publish_lock()
        self.assertEqual(e.exception.code, rt.RTAPI_ERROR_NOT_OWNER)
        self.assertIn("one writer", e.exception.message)
        b.disconnect()
        self.assertEqual(rt.connection_count("pysync"), 1)

    def test_errors(self):
        with self.assertRaises(rt.RTAPIError) as e:
            rt.connect("nosuchdomain", timeout=0)
        self.assertEqual(e.exception.code, rt.RTAPI_ERROR_DOMAIN_NOT_FOUND)
        self.assertIn("nosuchdomain", e.exception.detail)
        with rt.connect("pyasync", timeout=5) as conn:
            with self.assertRaises(rt.RTAPIError) as e:
                conn.subscribe("nope")
            self.assertEqual(e.exception.name, "RTAPI_ERROR_UNKNOWN_ITEM")
            with self.assertRaises(rt.RTAPIError) as e:
                conn.subscribe_unlock()
            self.assertEqual(e.exception.code, rt.RTAPI_ERROR_OUT_OF_ORDER)
        self.assertEqual(rt.error_message(12345), "unknown RTAPI return code")

    def test_framework_stop_is_reported_and_disconnects(self):
        conn = rt.connect("pyasync", timeout=5)
        self.host.stop()
        with self.assertRaises(rt.RTAPIError) as e:
            conn.subscribe("x")
        self.assertEqual(e.exception.code, rt.RTAPI_SUBSCRIBE_FAILED_RTLAB_SUBSYSTEM_UNMAPPED)
        self.assertFalse(conn.connected)
        self.assertIsNone(conn.status)
        conn.disconnect()


if __name__ == "__main__":
    unittest.main()
