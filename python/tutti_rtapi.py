"""Python binding of the tutti RTAPI: ctypes over librtapi.so, no compile step.

    import tutti_rtapi as rt
    with rt.connect("multiuav_uav2", timeout=5, ddf="ddf/multiuav.ddf") as conn:
        for _ in range(100):
            with conn.reading():                 # RTSubscribeLock ... RTSubscribeUnlock
                z = conn.subscribe("Z")          # a PUBLISH item (written by the framework)
            with conn.writing():                 # RTPublishLock ... RTPublishUnlock
                conn.publish("Elevation", 2 * z) # a SUBSCRIBE item (read by the framework)
    print(rt.connection_count("multiuav_uav2"))

The library is found through the environment variable TUTTI_RTAPI_LIB (a path to
librtapi.so), else the one the `tutti` wheel carries (tutti/lib/ beside this file), else in
../target/release then ../target/debug relative to this file (a checkout), else where an installed RTAPI is (launch-scripts/install.sh): pkg-config's
`rtapi` package, then the system's library path, then /usr/local/lib.

Item types: with a DDF (connect(..., ddf=PATH)) every item is converted according to its
DDF type. Without one, the library only tells the element size, and the type is assumed
from it: 8 bytes float64, 4 bytes float32, 2 bytes int16, 1 byte uint8; pass
types={"item": "int32", ...} to connect() to say otherwise. Arrays (length > 1) are read as
lists and written from sequences.

Every failing call raises RTAPIError, with .code (the RTAPI number), .name (RTAPI_...),
.message (RTGetErrorMessage) and .detail (RTGetLastErrorDetail). docs/rtapi.md has the table.
Threads may call at the same time; no call holds the library while it waits for the
framework (docs/rtapi.md, "Threads and state", says what threads must agree on).
"""

import contextlib
import ctypes
import ctypes.util
import os
import subprocess
import struct
import xml.etree.ElementTree as ET

__all__ = ["RTAPIError", "Connection", "connect", "connection_count", "error_message", "set_flag_delay", "CODES"]

#: Return codes: number -> name (the numbers are stable; see include/RTAPI.h).
CODES = {
    0: "RTAPI_SUCCESS",
    1: "RTAPI_SUBSCRIBE_FAILED_RTLAB_SUBSYSTEM_UNMAPPED",
    2: "RTAPI_PUBLISH_FAILED_RTLAB_SUBSYSTEM_UNMAPPED",
    3: "RTAPI_ERROR_NULL_POINTER",
    4: "RTAPI_ERROR_NOT_CONNECTED",
    5: "RTAPI_ERROR_UNKNOWN_CONNECTION_KEY",
    6: "RTAPI_ERROR_UNKNOWN_ITEM",
    7: "RTAPI_ERROR_WRONG_SIZE",
    8: "RTAPI_ERROR_TIMEOUT",
    9: "RTAPI_ERROR_DOMAIN_NOT_FOUND",
    10: "RTAPI_ERROR_LAYOUT_MISMATCH",
    11: "RTAPI_ERROR_DDF_INVALID",
    12: "RTAPI_ERROR_NOT_OWNER",
    13: "RTAPI_ERROR_TOO_MANY_CONNECTIONS",
    14: "RTAPI_ERROR_OUT_OF_ORDER",
    15: "RTAPI_ERROR_CORRUPT_SEGMENT",
    16: "RTAPI_ERROR_INTERNAL",
    17: "RTAPI_ERROR_ALREADY_CONNECTED",
    18: "RTAPI_ERROR_INVALID_ARGUMENT",
    19: "RTAPI_ERROR_CONNECTION_LOST",
    20: "RTAPI_ERROR_SYSTEM",
    21: "RTAPI_ERROR_VERSION_MISMATCH",
    22: "RTAPI_ERROR_REMOTE_NOT_SERVED",
    23: "RTAPI_ERROR_NOT_TRUSTED",
}
globals().update({name: code for code, name in CODES.items()})

#: Status word values (RTGetConnectionStatusPtr).
STATUS_RUNNING = 1
STATUS_STOPPED = 2

# DDF type names (canonical and aliases, lower case, single spaces) -> struct format.
_FORMATS = {
    "boolean": "?", "bool": "?",
    "int8": "b", "char": "b", "int16": "h", "short": "h", "int32": "i", "int": "i", "int64": "q", "long": "q",
    "unsigned int8": "B", "uint8": "B", "uchar": "B", "unsigned int16": "H", "uint16": "H",
    "unsigned int32": "I", "uint32": "I", "unsigned int64": "Q", "uint64": "Q",
    "float32": "f", "float": "f", "float64": "d", "double": "d",
}
_BY_SIZE = {8: "d", 4: "f", 2: "h", 1: "B"}


def _find_library():
    env = os.environ.get("TUTTI_RTAPI_LIB")
    if env:
        return env
    here = os.path.dirname(os.path.abspath(__file__))
    # The wheel's own library (the `tutti` package beside this module), before anything else.
    bundled = os.path.join(here, "tutti", "lib", "librtapi.so.0")
    if os.path.exists(bundled):
        return bundled
    for profile in ("release", "debug"):
        path = os.path.join(here, "..", "target", profile, "librtapi.so")
        if os.path.exists(path):
            return os.path.normpath(path)
    # An installed RTAPI: pkg-config first (it knows a prefix given in PKG_CONFIG_PATH).
    try:
        libdir = subprocess.run(
            ["pkg-config", "--variable=libdir", "rtapi"], capture_output=True, text=True, timeout=10, check=True
        ).stdout.strip()
        if libdir and os.path.exists(os.path.join(libdir, "librtapi.so.0")):
            return os.path.join(libdir, "librtapi.so.0")
    except (OSError, subprocess.SubprocessError):
        pass
    found = ctypes.util.find_library("rtapi")
    if found:
        return found
    for path in ("/usr/local/lib/librtapi.so.0", "/usr/lib/librtapi.so.0"):
        if os.path.exists(path):
            return path
    raise OSError(
        "librtapi.so not found: build it (cargo build --release -p tutti-rtapi), install it "
        "(launch-scripts/install.sh; add PREFIX/lib/pkgconfig to PKG_CONFIG_PATH), or set TUTTI_RTAPI_LIB"
    )


_lib = ctypes.CDLL(_find_library())
_c_uint_p = ctypes.POINTER(ctypes.c_uint)
_c_ushort_p = ctypes.POINTER(ctypes.c_ushort)
_SIGNATURES = {
    "RTNewConnectionKey": [_c_uint_p],
    "RTSetConnectionKey": [ctypes.c_uint],
    "RTConnect": [ctypes.c_char_p, ctypes.c_int],
    "RTConnectWithFile": [ctypes.c_char_p, ctypes.c_char_p, ctypes.c_int],
    "RTDisconnect": [],
    "RTPublish": [ctypes.c_char_p, ctypes.c_void_p, ctypes.c_uint],
    "RTSubscribe": [ctypes.c_char_p, ctypes.c_void_p, ctypes.c_uint],
    "RTPublishLock": [], "RTPublishUnlock": [], "RTSubscribeLock": [], "RTSubscribeUnlock": [],
    "RTGetKeyForItem": [ctypes.c_char_p, _c_ushort_p],
    "RTGetInfoForItem": [ctypes.c_char_p, _c_uint_p, _c_ushort_p],
    "RTGetBuffer": [ctypes.c_uint, ctypes.c_ushort, ctypes.POINTER(ctypes.c_void_p)],
    "RTGetConnectionStatusPtr": [ctypes.c_uint, ctypes.POINTER(_c_uint_p)],
    "RTWaitReadyToGo": [],
    "RTSetSkipWaitToGoAtConnection": [ctypes.c_bool],
    "RTDefineFlagDelay": [ctypes.c_uint],
    "RTUseFlagWithTool": [ctypes.c_uint],
    "RTGetConnectionCount": [ctypes.c_char_p, _c_uint_p],
    "RTSetupRefMemRemoteConnection": [ctypes.c_char_p, ctypes.c_int],
    "RTRequestTime": [ctypes.c_double],
    "RTSetWakeOnChange": [ctypes.c_bool],
    "RTSetPeriod": [ctypes.c_double],
    "RTGetSimulationTime": [ctypes.POINTER(ctypes.c_double)],
}
# RTSetStateCallbacks: a connection's state, handed over and taken back as bytes (docs/rtapi.md).
_SAVE_CB = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.POINTER(ctypes.c_void_p), _c_uint_p)
_RESTORE_CB = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_uint)
_SIGNATURES["RTSetStateCallbacks"] = [_SAVE_CB, _RESTORE_CB, ctypes.c_void_p]
for _name, _args in _SIGNATURES.items():
    _fn = getattr(_lib, _name)
    _fn.argtypes = _args
    _fn.restype = ctypes.c_int
_lib.RTGetErrorMessage.argtypes = [ctypes.c_int]
_lib.RTGetErrorMessage.restype = ctypes.c_char_p
_lib.RTGetLastErrorDetail.argtypes = []
_lib.RTGetLastErrorDetail.restype = ctypes.c_char_p


def error_message(code):
    """The library's text for a return code."""
    return _lib.RTGetErrorMessage(code).decode()


class RTAPIError(Exception):
    """A failed RTAPI call: .code, .name, .message, .detail, .call."""

    def __init__(self, call, code):
        self.call = call
        self.code = code
        self.name = CODES.get(code, "unknown")
        self.message = error_message(code)
        self.detail = _lib.RTGetLastErrorDetail().decode(errors="replace")
        super().__init__(f"{call}: {self.name} ({code}): {self.message}" + (f" [{self.detail}]" if self.detail else ""))


def _call(name, *args):
    rc = getattr(_lib, name)(*args)
    if rc != 0:
        raise RTAPIError(name, rc)


def _b(text):
    return text.encode() if isinstance(text, str) else text


def connection_count(domain):
    """Connections now in `domain` (works without being connected)."""
    n = ctypes.c_uint()
    _call("RTGetConnectionCount", _b(domain), ctypes.byref(n))
    return n.value


def set_flag_delay(microseconds):
    """Wait by polling every `microseconds` (0: spin) instead of sleeping in the kernel."""
    _call("RTDefineFlagDelay", microseconds)


def _ddf_types(path, domain):
    """Item path -> struct format, for every item of `domain` in the DDF at `path`."""
    root = ET.parse(path).getroot()
    types = {}

    def walk(items, prefix):
        for item in items:
            name = prefix + item.get("name", "")
            ty = " ".join((item.findtext("type") or "").split()).lower()
            if ty == "bus":
                walk(item.findall("item"), name + "/")
            elif ty in _FORMATS:
                types[name] = _FORMATS[ty]

    for d in root.iter("domain"):
        if d.get("name") == domain:
            for s in list(d.findall("set")) + list(d.findall("block")):
                walk(s.findall("item"), "")
    return types


class Connection:
    """One RTAPI connection (its own connection key)."""

    def __init__(self, domain, timeout=5, ddf=None, types=None, skip_wait_to_go=False, state=None):
        self.domain = domain
        key = ctypes.c_uint()
        _call("RTNewConnectionKey", ctypes.byref(key))
        self.key = key.value
        self._types = _ddf_types(ddf, domain) if ddf else {}
        self._types.update({k: _FORMATS[v.lower()] for k, v in (types or {}).items()})
        self._info = {}
        self._select()
        _call("RTSetSkipWaitToGoAtConnection", bool(skip_wait_to_go))
        if state is not None:
            self._set_state(*state)
        if ddf:
            _call("RTConnectWithFile", _b(os.fspath(ddf)), _b(domain), int(timeout))
        else:
            _call("RTConnect", _b(domain), int(timeout))
        self.connected = True
        status = _c_uint_p()
        _call("RTGetConnectionStatusPtr", self.key, ctypes.byref(status))
        self._status = status

    def _select(self):
        _call("RTSetConnectionKey", self.key)

    def _set_state(self, save, restore):
        """RTSetStateCallbacks: `save()` returns the component's state as bytes, `restore(b)`
        takes such bytes back; both are called at a step boundary from within reading() (or
        writing()) while it waits for the next step. An exception fails the checkpoint."""
        holder = {}

        def on_save(_ctx, buffer, size):
            try:
                data = bytes(save())
            except Exception:  # the checkpoint names the component; its own words go to stderr
                import traceback
                traceback.print_exc()
                return 1
            holder["last"] = ctypes.create_string_buffer(data, len(data) or 1)
            buffer[0] = ctypes.cast(holder["last"], ctypes.c_void_p)
            size[0] = len(data)
            return 0

        def on_restore(_ctx, buffer, size):
            try:
                restore(ctypes.string_at(buffer, size) if size else b"")
            except Exception:
                import traceback
                traceback.print_exc()
                return 1
            return 0

        # Kept alive as long as the connection: the library calls them later.
        self._state_callbacks = (_SAVE_CB(on_save), _RESTORE_CB(on_restore), holder)
        self._select()
        _call("RTSetStateCallbacks", self._state_callbacks[0], self._state_callbacks[1], None)

    def set_state_callbacks(self, save, restore):
        """This connection keeps a state for checkpoints (docs/rtapi.md, "Checkpoints"):
        `save()` returns bytes, `restore(data)` takes them back. Prefer connect(..., state=(save,
        restore)), which says so from the start (the run's checkpoint of step 0 then has it)."""
        self._set_state(save, restore)

    def _item(self, item):
        """(struct format of one element, element count, total size) of an item."""
        if item not in self._info:
            self._select()
            size, length = ctypes.c_uint(), ctypes.c_ushort()
            _call("RTGetInfoForItem", _b(item), ctypes.byref(size), ctypes.byref(length))
            fmt = self._types.get(item) or _BY_SIZE.get(size.value)
            if fmt is None or struct.calcsize(fmt) != size.value:
                raise TypeError(f"item '{item}': cannot tell the type of {size.value}-byte elements; pass types={{...}} or ddf=")
            self._info[item] = (fmt, length.value, size.value * length.value)
        return self._info[item]

    def item_key(self, item):
        """The RTAPI item key (PUBLISH items first, then SUBSCRIBE)."""
        self._select()
        key = ctypes.c_ushort()
        _call("RTGetKeyForItem", _b(item), ctypes.byref(key))
        return key.value

    def item_info(self, item):
        """(element size in bytes, element count)."""
        fmt, length, size = self._item(item)
        return size // length, length

    def subscribe(self, item):
        """Reads a PUBLISH item: a number (or bool), or a list for arrays."""
        fmt, length, size = self._item(item)
        buf = ctypes.create_string_buffer(size)
        self._exchange("RTSubscribe", _b(item), buf, size)
        values = struct.unpack(f"={length}{fmt}", buf.raw)
        return values[0] if length == 1 else list(values)

    def publish(self, item, value):
        """Writes a SUBSCRIBE item from a number (or bool), or a sequence for arrays."""
        fmt, length, size = self._item(item)
        values = [value] if length == 1 and not isinstance(value, (list, tuple)) else list(value)
        if len(values) != length:
            raise ValueError(f"item '{item}' has {length} elements, got {len(values)}")
        data = struct.pack(f"={length}{fmt}", *values)
        self._exchange("RTPublish", _b(item), data, size)

    def _exchange(self, name, *args):
        """Calls `name` on this connection; an error that closed it marks it closed."""
        self._select()
        try:
            _call(name, *args)
        except RTAPIError as e:
            if e.code in (1, 2, 19):
                # The framework went away: release the connection (the library keeps it,
                # answering these codes, until RTDisconnect).
                _lib.RTDisconnect()
                self.connected = False
                self._status = None
            raise

    def setup_ref_mem_remote_connection(self, card, pci_index):
        """RTSetupRefMemRemoteConnection: checks that this (remote) domain is served on this
        machine, by its framework or a `tutti gateway --mirror`; RTAPIError 22 otherwise."""
        self._exchange("RTSetupRefMemRemoteConnection", _b(card), int(pci_index))

    def subscribe_lock(self):
        self._exchange("RTSubscribeLock")

    def subscribe_unlock(self):
        self._exchange("RTSubscribeUnlock")

    def publish_lock(self):
        self._exchange("RTPublishLock")

    def publish_unlock(self):
        self._exchange("RTPublishUnlock")

    @contextlib.contextmanager
    def reading(self):
        """RTSubscribeLock ... RTSubscribeUnlock."""
        self.subscribe_lock()
        try:
            yield self
        finally:
            if self.connected:
                self.subscribe_unlock()

    @contextlib.contextmanager
    def writing(self):
        """RTPublishLock ... RTPublishUnlock (the commit happens at the end of the block)."""
        self.publish_lock()
        try:
            yield self
        finally:
            if self.connected:
                self.publish_unlock()

    def wait_ready_to_go(self):
        self._exchange("RTWaitReadyToGo")

    # Event-driven domains (tutti's extensions, docs/timing.md). In a lock-step or
    # asynchronous domain they change nothing: the connection is due at every step there.

    def request_time(self, sim_time):
        """RTRequestTime: next due at the first step at or after `sim_time` (seconds)."""
        self._exchange("RTRequestTime", float(sim_time))

    def set_wake_on_change(self, on=True):
        """RTSetWakeOnChange: also due at any step whose PUBLISH set changed."""
        self._exchange("RTSetWakeOnChange", bool(on))

    def set_period(self, seconds):
        """RTSetPeriod: due every `seconds` of simulated time (a whole multiple of the step)."""
        self._exchange("RTSetPeriod", float(seconds))

    def simulation_time(self):
        """RTGetSimulationTime: the simulated time of the step this connection is at."""
        t = ctypes.c_double()
        self._exchange("RTGetSimulationTime", ctypes.byref(t))
        return t.value

    @property
    def status(self):
        """The framework's live status word: 1 running, 2 stopped; None once disconnected."""
        return self._status[0] if self.connected and self._status else None

    def connection_count(self):
        return connection_count(self.domain)

    def disconnect(self):
        if self.connected:
            self.connected = False
            self._status = None
            self._select()
            _call("RTDisconnect")

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.disconnect()


def connect(domain, timeout=5, ddf=None, types=None, skip_wait_to_go=False, state=None):
    """Connects to `domain` (checking it against `ddf` when given); returns a Connection.
    `state=(save, restore)`: the connection keeps a state for checkpoints (save() -> bytes,
    restore(bytes)), said from the start."""
    return Connection(domain, timeout=timeout, ddf=ddf, types=types, skip_wait_to_go=skip_wait_to_go, state=state)
