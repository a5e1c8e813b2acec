//! A minimal framework for tests of RTAPI clients in other languages (the Python tests):
//! hosts every domain of a DDF and steps them every PERIOD_MS; every float64 element of a
//! PUBLISH set holds the step number. Prints `ready` once the domains exist, and after each
//! step nothing. Stops, removing its segments, when its stdin closes or after MAX_SECONDS.
//! With `--echo`, prints each domain's SUBSCRIBE float64 items after every step
//! (`DOMAIN STEP ITEM=VALUE ...`).
//!
//! Checkpoints (docs/rtapi.md): a stdin line `save` asks every connection that keeps a state
//! for it between two steps and prints `saved DOMAIN NAME HEX` for each (`failed DOMAIN NAME
//! WHY` when it cannot); `restore DOMAIN NAME HEX` hands those bytes back and prints `restored
//! DOMAIN NAME` (or `failed …`).
//!
//!     rtapi_test_host DDF PERIOD_MS MAX_SECONDS [--echo]

use std::io::{BufRead, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use tutti_core::ddf::{self, Role, ScalarType};
use tutti_core::shm::{Framework, FrameworkOptions, StateAnswer, StateRequest};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 4 {
        eprintln!("usage: rtapi_test_host DDF PERIOD_MS MAX_SECONDS [--echo]");
        std::process::exit(2);
    }
    let model = ddf::load(&args[1])?;
    let period = Duration::from_millis(args[2].parse()?);
    let limit = Duration::from_secs(args[3].parse()?);
    let echo = args.get(4).is_some_and(|a| a == "--echo");
    let opts = FrameworkOptions { timeout: Duration::from_secs(10), ..Default::default() };
    let mut fw = Framework::create(&model, &opts)?;
    for host in &fw.domains {
        // Event-driven participants turn times into steps with it.
        host.set_sim_step(period.as_secs_f64());
    }
    let stop = Arc::new(AtomicBool::new(false));
    let stop2 = stop.clone();
    let (commands, received) = std::sync::mpsc::channel::<String>();
    std::thread::spawn(move || {
        for line in std::io::stdin().lock().lines() {
            let Ok(line) = line else { break };
            let _ = commands.send(line);
        }
        stop2.store(true, Ordering::Release);
    });
    let mut out = std::io::stdout().lock();
    writeln!(out, "ready")?;
    out.flush()?;
    let start = Instant::now();
    let mut k = 0u64;
    while !stop.load(Ordering::Acquire) && start.elapsed() < limit {
        k += 1;
        for host in &mut fw.domains {
            let info = host.info().clone();
            let mut buf = vec![0u8; info.publish.size as usize];
            for leaf in info.set(Role::Publish).leaves.iter().filter(|l| l.ty == ScalarType::Float64) {
                for e in 0..usize::from(leaf.length) {
                    let off = leaf.offset as usize + 8 * e;
                    buf[off..off + 8].copy_from_slice(&(k as f64).to_ne_bytes());
                }
            }
            host.step(&buf, k as f64 * period.as_secs_f64())?;
            if echo {
                let sub = host.subscribe();
                let mut line = format!("{} {}", info.name, host.current_step());
                for leaf in
                    info.set(Role::Subscribe).leaves.iter().filter(|l| l.ty == ScalarType::Float64 && l.length == 1)
                {
                    let v = f64::from_ne_bytes(sub[leaf.range()].try_into()?);
                    line.push_str(&format!(" {}={v}", leaf.path));
                }
                writeln!(out, "{line}")?;
            }
        }
        while let Ok(command) = received.try_recv() {
            checkpoint(&fw, &command, &mut out)?;
        }
        out.flush()?;
        std::thread::sleep(period);
    }
    Ok(())
}

/// A checkpoint command between two steps (see the module).
fn checkpoint(fw: &Framework, command: &str, out: &mut impl Write) -> Result<(), Box<dyn std::error::Error>> {
    let words: Vec<&str> = command.split_whitespace().collect();
    let (kind, target) = match words.as_slice() {
        ["save"] => (StateRequest::Save, None),
        ["restore", domain, name, hex] => (StateRequest::Restore, Some((*domain, *name, unhex(hex)))),
        _ => return Ok(()),
    };
    let conns: Vec<_> = fw.domains.iter().map(|d| d.state_connections()).collect();
    let mut asked = Vec::new();
    for (d, list) in fw.domains.iter().zip(&conns) {
        let mine: Vec<_> = list
            .iter()
            .filter(|c| c.keeps_state)
            .filter(|c| target.as_ref().map_or(true, |(dom, name, _)| *dom == d.info().name && *name == c.name))
            .map(|c| (c, target.as_ref().map_or(&[][..], |t| &t.2[..])))
            .collect();
        asked.push(mine);
    }
    let answers = fw.exchange_states(kind, &asked, Duration::from_secs(10))?;
    for ((d, mine), answers) in fw.domains.iter().zip(&asked).zip(answers) {
        for ((c, _), answer) in mine.iter().zip(answers) {
            let (domain, name) = (&d.info().name, &c.name);
            match answer {
                StateAnswer::Saved(bytes) => writeln!(out, "saved {domain} {name} {}", hex(&bytes))?,
                StateAnswer::Restored => writeln!(out, "restored {domain} {name}")?,
                StateAnswer::Failed(why) => writeln!(out, "failed {domain} {name} {why}")?,
                StateAnswer::NoAnswer => writeln!(out, "failed {domain} {name} no answer")?,
            }
        }
    }
    Ok(())
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

fn unhex(s: &str) -> Vec<u8> {
    (0..s.len() / 2).filter_map(|i| u8::from_str_radix(s.get(2 * i..2 * i + 2)?, 16).ok()).collect()
}
