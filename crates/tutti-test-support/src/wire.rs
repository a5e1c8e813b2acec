//! A link between two network namespaces with a delay, losses, reordering and cuts, made in
//! userspace: a TAP device in each namespace, and threads of this process that copy each
//! Ethernet frame from one device to the other once its delay has passed. Every protocol
//! crosses it unchanged (ARP, DDS discovery's multicast, TCP), as over a wire with a delay:
//! this kernel has no `tc netem`, and a UDP relay would not do for DDS, whose discovery
//! carries each side's own addresses.
//!
//! Needs root (network namespaces, TAP devices) and `ip` of iproute2; [`Wire::create`] says
//! why when it cannot. Dropping the wire stops its threads and deletes both namespaces (and
//! the devices with them).

use std::collections::BinaryHeap;
use std::fs::File;
use std::io::{Read, Write};
use std::os::fd::{AsRawFd, FromRawFd, OwnedFd};
use std::process::Command;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex, PoisonError};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

use crate::SetupError;

/// What the wire does to the frames that cross it, each way; changed while it runs.
#[derive(Debug, Default)]
pub struct Faults {
    /// The delay of every frame, µs.
    pub delay_us: AtomicU64,
    /// Frames dropped, in parts per million.
    pub loss_ppm: AtomicU64,
    /// Frames held back by an extra delay (so that later ones overtake them), in parts per
    /// million, and that extra delay (µs).
    pub reorder_ppm: AtomicU64,
    pub reorder_us: AtomicU64,
    /// The wire is cut: every frame is dropped.
    pub cut: AtomicBool,
}

/// Two network namespaces joined by a wire; see the module's docs.
#[derive(Debug)]
pub struct Wire {
    names: [String; 2],
    faults: Arc<Faults>,
    stop: Arc<AtomicBool>,
    threads: Vec<JoinHandle<()>>,
    /// Frames copied and frames dropped, both ways together.
    counts: Arc<[AtomicU64; 2]>,
}

impl Wire {
    /// The address of each side, on its TAP device `tap0` (a /24).
    pub const ADDRS: [&'static str; 2] = ["192.0.2.1", "192.0.2.2"];

    /// Makes the two namespaces (named after `tag` and this process) and the wire between
    /// them, with `delay` each way; Err with the reason when this machine does not let it.
    pub fn create(tag: &str, delay: Duration) -> Result<Wire, SetupError> {
        let names = [0, 1].map(|i| format!("tutti-{}-{tag}-{i}", std::process::id()));
        let mut wire = Wire {
            names: names.clone(),
            faults: Arc::new(Faults::default()),
            stop: Arc::new(AtomicBool::new(false)),
            threads: Vec::new(),
            counts: Arc::new([AtomicU64::new(0), AtomicU64::new(0)]),
        };
        wire.set_delay(delay);
        let ip = |args: &[&str]| crate::run_tool("ip", args);
        let mut taps = Vec::new();
        for n in &names {
            ip(&["netns", "add", n])?;
            taps.push(tap_in(n)?);
            ip(&["-n", n, "link", "set", "lo", "up"])?;
        }
        for (n, addr) in names.iter().zip(Self::ADDRS) {
            ip(&["-n", n, "addr", "add", &format!("{addr}/24"), "dev", "tap0"])?;
            ip(&["-n", n, "link", "set", "tap0", "up", "multicast", "on"])?;
            ip(&["-n", n, "route", "add", "224.0.0.0/4", "dev", "tap0"])?;
        }
        let (a, b) = (File::from(taps.remove(0)), File::from(taps.remove(0)));
        let (a2, b2) = (
            a.try_clone().map_err(SetupError::os("a TAP device"))?,
            b.try_clone().map_err(SetupError::os("a TAP device"))?,
        );
        wire.direction(a, b2)?;
        wire.direction(b, a2)?;
        Ok(wire)
    }

    /// The two namespaces' names (`ip netns exec NAME ...` runs a program on one side).
    pub fn names(&self) -> &[String; 2] {
        &self.names
    }

    /// What the wire does, to change while it runs (from any thread).
    pub fn faults(&self) -> Arc<Faults> {
        self.faults.clone()
    }

    pub fn set_delay(&self, d: Duration) {
        self.faults.delay_us.store(u64::try_from(d.as_micros()).unwrap_or(u64::MAX), Ordering::Relaxed);
    }

    /// Cuts the wire (every frame dropped) or joins it again.
    pub fn set_cut(&self, cut: bool) {
        self.faults.cut.store(cut, Ordering::Relaxed);
    }

    /// Frames copied and frames dropped so far, both ways together.
    pub fn counts(&self) -> (u64, u64) {
        (self.counts[0].load(Ordering::Relaxed), self.counts[1].load(Ordering::Relaxed))
    }

    /// Starts one direction: frames read from `from` are written to `to` when due.
    fn direction(&mut self, mut from: File, mut to: File) -> Result<(), SetupError> {
        let queue = Arc::new((Mutex::new(BinaryHeap::<Frame>::new()), Condvar::new()));
        let (q, faults, stop, counts) = (queue.clone(), self.faults.clone(), self.stop.clone(), self.counts.clone());
        let reader = thread::Builder::new()
            .name("tutti-wire-rx".into())
            .spawn(move || {
                let mut seq = 0u64;
                let mut rng = 0x9e37_79b9_7f4a_7c15_u64 ^ u64::from(std::process::id());
                let mut buf = vec![0u8; 65536];
                while !stop.load(Ordering::Relaxed) {
                    if !readable(&from, 50) {
                        continue;
                    }
                    let Ok(n) = from.read(&mut buf) else { continue };
                    let now = Instant::now();
                    let draw = |rng: &mut u64| {
                        // xorshift64: enough for drawing which frames to drop.
                        *rng ^= *rng << 13;
                        *rng ^= *rng >> 7;
                        *rng ^= *rng << 17;
                        *rng % 1_000_000
                    };
                    if faults.cut.load(Ordering::Relaxed) || draw(&mut rng) < faults.loss_ppm.load(Ordering::Relaxed) {
                        counts[1].fetch_add(1, Ordering::Relaxed);
                        continue;
                    }
                    let mut delay = faults.delay_us.load(Ordering::Relaxed);
                    if draw(&mut rng) < faults.reorder_ppm.load(Ordering::Relaxed) {
                        delay += faults.reorder_us.load(Ordering::Relaxed);
                    }
                    seq += 1;
                    let frame = Frame { due: now + Duration::from_micros(delay), seq, bytes: buf[..n].to_vec() };
                    let (lock, cv) = &*q;
                    lock.lock().unwrap_or_else(PoisonError::into_inner).push(frame);
                    cv.notify_one();
                }
            })
            .map_err(SetupError::os("the wire's reading thread"))?;
        let (stop, counts) = (self.stop.clone(), self.counts.clone());
        let writer = thread::Builder::new()
            .name("tutti-wire-tx".into())
            .spawn(move || {
                let (lock, cv) = &*queue;
                let mut heap = lock.lock().unwrap_or_else(PoisonError::into_inner);
                while !stop.load(Ordering::Relaxed) {
                    let now = Instant::now();
                    match heap.peek().map(|f| f.due) {
                        Some(due) if due <= now => {
                            if let Some(f) = heap.pop() {
                                drop(heap);
                                // A full device queue drops the frame, as a wire would.
                                let _ = to.write(&f.bytes);
                                counts[0].fetch_add(1, Ordering::Relaxed);
                                heap = lock.lock().unwrap_or_else(PoisonError::into_inner);
                            }
                        }
                        Some(due) => {
                            let wait = (due - now).min(Duration::from_millis(50));
                            heap = cv.wait_timeout(heap, wait).unwrap_or_else(PoisonError::into_inner).0;
                        }
                        None => {
                            heap = cv
                                .wait_timeout(heap, Duration::from_millis(50))
                                .unwrap_or_else(PoisonError::into_inner)
                                .0;
                        }
                    }
                }
            })
            .map_err(SetupError::os("the wire's writing thread"))?;
        self.threads.push(reader);
        self.threads.push(writer);
        Ok(())
    }
}

impl Drop for Wire {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
        // Deleting a namespace deletes its TAP device (the process's file is closed above).
        for n in &self.names {
            let _ = Command::new("ip").args(["netns", "del", n]).status();
        }
    }
}

/// A frame on its way, ordered by when it is due (the earliest first, then the order read).
struct Frame {
    due: Instant,
    seq: u64,
    bytes: Vec<u8>,
}

impl PartialEq for Frame {
    fn eq(&self, o: &Self) -> bool {
        (self.due, self.seq) == (o.due, o.seq)
    }
}
impl Eq for Frame {}
impl PartialOrd for Frame {
    fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Frame {
    fn cmp(&self, o: &Self) -> std::cmp::Ordering {
        // BinaryHeap is a max-heap: the earliest is the greatest.
        (o.due, o.seq).cmp(&(self.due, self.seq))
    }
}

/// Whether `f` has a frame to read within `ms` milliseconds.
fn readable(f: &File, ms: i32) -> bool {
    let mut p = libc::pollfd { fd: f.as_raw_fd(), events: libc::POLLIN, revents: 0 };
    // SAFETY: one valid pollfd, for the duration of the call.
    let n = unsafe { libc::poll(&mut p, 1, ms) };
    n > 0 && p.revents & libc::POLLIN != 0
}

/// A TAP device `tap0` made in network namespace `ns` (by a thread that enters it: a device
/// is made in its creator's namespace and stays there), as an open file of this process.
fn tap_in(ns: &str) -> Result<OwnedFd, SetupError> {
    let path = format!("/var/run/netns/{ns}");
    let made = thread::scope(|s| {
        s.spawn(|| -> Result<OwnedFd, SetupError> {
            let nsf = File::open(&path).map_err(SetupError::os(path.as_str()))?;
            // SAFETY: a valid descriptor of a network namespace; only this thread moves.
            if unsafe { libc::setns(nsf.as_raw_fd(), libc::CLONE_NEWNET) } != 0 {
                return Err(SetupError::last_os(format!("entering {ns}")));
            }
            let tun = std::fs::OpenOptions::new()
                .read(true)
                .write(true)
                .open("/dev/net/tun")
                .map_err(SetupError::os("/dev/net/tun"))?;
            // SAFETY: an ifreq zeroed, its name and flags set as TUNSETIFF reads them.
            let mut req: libc::ifreq = unsafe { std::mem::zeroed() };
            for (d, s) in req.ifr_name.iter_mut().zip(b"tap0") {
                *d = *s as libc::c_char;
            }
            req.ifr_ifru.ifru_flags = (libc::IFF_TAP | libc::IFF_NO_PI) as libc::c_short;
            // SAFETY: TUNSETIFF on a /dev/net/tun descriptor, with a valid ifreq.
            if unsafe { libc::ioctl(tun.as_raw_fd(), libc::TUNSETIFF, &mut req) } != 0 {
                return Err(SetupError::last_os(format!("TUNSETIFF in {ns}")));
            }
            // SAFETY: the descriptor is taken out of the File, which no longer closes it.
            Ok(unsafe { OwnedFd::from_raw_fd(std::os::fd::IntoRawFd::into_raw_fd(tun)) })
        })
        .join()
        .map_err(|_| SetupError::Panicked("the thread that made the TAP device"))?
    });
    made
}
