//! A child process with a watchdog, killed when dropped.

use std::io::{BufRead, BufReader, Read};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

/// How [`Proc::spawn_with`] starts a child.
#[derive(Debug, Clone)]
pub struct Spawn {
    /// The child is killed once it has run this long.
    pub watchdog: Duration,
    /// Collect stdout line by line ([`Proc::lines`]); otherwise it stays as the command has it.
    pub stdout: bool,
    /// Collect stderr line by line (prefixed `stderr: `); otherwise it stays as the command
    /// has it.
    pub stderr: bool,
    /// Start the child in a process group of its own, and kill the whole group on drop (a
    /// child that starts children of its own: a browser).
    pub process_group: bool,
    /// On drop, SIGINT first and this long to exit (a `tutti` process removes its segments),
    /// then SIGKILL; zero: SIGKILL at once.
    pub grace: Duration,
}

impl Default for Spawn {
    fn default() -> Self {
        Spawn {
            watchdog: Duration::from_secs(120),
            stdout: true,
            stderr: true,
            process_group: false,
            grace: Duration::from_secs(3),
        }
    }
}

/// A child process killed, with its output kept, when it outlives its watchdog or when it is
/// dropped (so that a failing test leaves nothing running). stdin is /dev/null; a command
/// without a working directory runs in the repository root.
#[derive(Debug)]
pub struct Proc {
    /// Shown in messages.
    pub name: String,
    pid: u32,
    child: Arc<Mutex<Child>>,
    lines: Arc<Mutex<Vec<String>>>,
    done: Arc<AtomicBool>,
    readers: Vec<JoinHandle<()>>,
    opts: Spawn,
    status: Option<ExitStatus>,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

impl Proc {
    /// Starts `cmd` with its output collected and a watchdog of `watchdog`.
    pub fn spawn(name: &str, cmd: Command, watchdog: Duration) -> Proc {
        Proc::spawn_with(name, cmd, Spawn { watchdog, ..Spawn::default() })
    }

    /// Starts `cmd` as `opts` says.
    pub fn spawn_with(name: &str, mut cmd: Command, opts: Spawn) -> Proc {
        cmd.stdin(Stdio::null());
        if cmd.get_current_dir().is_none() {
            cmd.current_dir(crate::repo_root());
        }
        if opts.stdout {
            cmd.stdout(Stdio::piped());
        }
        if opts.stderr {
            cmd.stderr(Stdio::piped());
        }
        if opts.process_group {
            use std::os::unix::process::CommandExt;
            cmd.process_group(0);
        }
        let mut child = cmd.spawn().unwrap_or_else(|e| panic!("starting {name} ({cmd:?}): {e}"));
        let lines = Arc::new(Mutex::new(Vec::new()));
        let out = child.stdout.take().filter(|_| opts.stdout).map(|s| Box::new(s) as Box<dyn Read + Send>);
        let err = child.stderr.take().filter(|_| opts.stderr).map(|s| Box::new(s) as Box<dyn Read + Send>);
        let mut readers = Vec::new();
        for (tag, s) in [("", out), ("stderr: ", err)] {
            let Some(s) = s else { continue };
            let lines = lines.clone();
            readers.push(thread::spawn(move || {
                let mut r = BufReader::new(s);
                let mut buf = Vec::new();
                while r.read_until(b'\n', &mut buf).is_ok_and(|n| n > 0) {
                    let l = String::from_utf8_lossy(&buf);
                    lock(&lines).push(format!("{tag}{}", l.trim_end_matches(['\n', '\r'])));
                    buf.clear();
                }
            }));
        }
        let pid = child.id();
        let child = Arc::new(Mutex::new(child));
        let done = Arc::new(AtomicBool::new(false));
        {
            let (child, done, name, limit) = (child.clone(), done.clone(), name.to_string(), opts.watchdog);
            thread::spawn(move || {
                if crate::poll_for(limit, || done.load(Ordering::Acquire).then_some(())).is_none() {
                    eprintln!("watchdog: killing {name} after {limit:?}");
                    let _ = lock(&child).kill();
                }
            });
        }
        Proc { name: name.to_string(), pid, child, lines, done, readers, opts, status: None }
    }

    /// The child's process id.
    pub fn id(&self) -> u32 {
        self.pid
    }

    /// Lines printed so far (stderr lines prefixed `stderr: `).
    pub fn lines(&self) -> Vec<String> {
        lock(&self.lines).clone()
    }

    /// What it printed on stdout so far, one line after the other.
    pub fn stdout(&self) -> String {
        self.lines().iter().filter(|l| !l.starts_with("stderr: ")).fold(String::new(), |s, l| s + l + "\n")
    }

    /// What it printed on stderr so far, one line after the other.
    pub fn stderr(&self) -> String {
        self.lines().iter().filter_map(|l| l.strip_prefix("stderr: ")).fold(String::new(), |s, l| s + l + "\n")
    }

    /// Waits until a line contains `pat`; returns it.
    pub fn wait_line(&self, pat: &str, timeout: Duration) -> Option<String> {
        let mut from = 0;
        self.next_line(&mut from, pat, timeout)
    }

    /// Waits until a line from index `*from` on contains `pat`; returns it and moves `*from`
    /// past it. A zero `timeout` looks once.
    pub fn next_line(&self, from: &mut usize, pat: &str, timeout: Duration) -> Option<String> {
        let (i, l) = crate::poll_for(timeout, || {
            self.lines().into_iter().enumerate().skip(*from).find(|(_, l)| l.contains(pat))
        })?;
        *from = i + 1;
        Some(l)
    }

    /// Whether it has exited (its status is then kept).
    pub fn exited(&mut self) -> Option<ExitStatus> {
        if self.status.is_none() {
            self.status = lock(&self.child).try_wait().ok().flatten();
        }
        self.status
    }

    /// Waits for the exit at most `timeout`; on a timeout kills the child and returns `None`.
    /// Once it has exited, its output is all collected.
    pub fn wait_status(&mut self, timeout: Duration) -> Option<ExitStatus> {
        let end = Instant::now() + timeout;
        let mut timed_out = false;
        let status = loop {
            if let Some(s) = self.exited() {
                break s;
            }
            if Instant::now() >= end && !timed_out {
                timed_out = true;
                let _ = lock(&self.child).kill();
            }
            thread::sleep(Duration::from_millis(10));
        };
        self.done.store(true, Ordering::Release);
        for r in self.readers.drain(..) {
            let _ = r.join();
        }
        (!timed_out).then_some(status)
    }

    /// Waits for the exit (at most `timeout`, then kills); returns the status code (`None`
    /// when a signal ended it).
    pub fn wait(&mut self, timeout: Duration) -> Option<i32> {
        self.wait_status(timeout);
        self.status.and_then(|s| s.code())
    }

    /// Sends signal `sig` (`INT`, `TERM`, `KILL`, …) to the child.
    pub fn signal(&self, sig: &str) {
        let _ = Command::new("kill").args([&format!("-{sig}"), &self.pid.to_string()]).status();
    }

    /// Sends SIGINT (a clean stop) and waits at most `timeout`; returns the status code.
    pub fn interrupt(&mut self, timeout: Duration) -> Option<i32> {
        self.signal("INT");
        self.wait(timeout)
    }

    /// Its name and everything it printed, for a failure message.
    pub fn dump(&self) -> String {
        format!("--- {} ---\n{}", self.name, self.lines().join("\n"))
    }

    /// A handle on what it prints, for the failure messages of code that does not hold the
    /// process (a client's call that fails while the server is held elsewhere).
    pub fn output(&self) -> Output {
        Output { name: self.name.clone(), lines: self.lines.clone() }
    }

    /// SIGKILL: the process gets no chance to say goodbye; waits for its exit.
    pub fn kill9(&mut self) {
        let _ = lock(&self.child).kill();
        self.wait(Duration::from_secs(10));
    }
}

/// What a [`Proc`] printed, read at any time ([`Proc::output`]).
#[derive(Debug, Clone)]
pub struct Output {
    name: String,
    lines: Arc<Mutex<Vec<String>>>,
}

impl Output {
    /// Its name and everything it printed so far, as [`Proc::dump`] shows them.
    pub fn dump(&self) -> String {
        format!("--- {} ---\n{}", self.name, lock(&self.lines).join("\n"))
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        self.done.store(true, Ordering::Release);
        let mut c = lock(&self.child);
        if let Ok(None) = c.try_wait() {
            if !self.opts.grace.is_zero() {
                // A clean stop first (a framework or a mirror removes its segments).
                let _ = Command::new("kill").args(["-INT", &self.pid.to_string()]).status();
                let end = Instant::now() + self.opts.grace;
                while Instant::now() < end && matches!(c.try_wait(), Ok(None)) {
                    thread::sleep(Duration::from_millis(10));
                }
            }
            let _ = c.kill();
            let _ = c.wait();
        }
        if self.opts.process_group {
            let group = format!("-{}", self.pid);
            let _ = Command::new("kill").args(["-KILL", "--", &group]).stderr(Stdio::null()).status();
        }
    }
}
