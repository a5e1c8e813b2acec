//! `tutti ctl state|pause|resume|step N|speed X|seek T|reset [state]|stop [--json]`, `tutti ctl save|restore
//! FILE` (checkpoints), and `tutti ctl
//! restart|stop|start COMPONENT`, `tutti ctl signal COMPONENT SIGNAL`: acts on the run of the namespace through its control
//! plane (`tutti_host::control`, docs/run.md).

use std::time::{Duration, Instant};

use tutti_core::parse::parse_duration;
use tutti_core::shm::segment::namespace_from_env;
use tutti_host::control::{ComponentAction, ControlClient, ControlError, Request, RunStatus};

use super::{CliResult, Failure};

/// Control the running framework of the namespace (TUTTI_NAMESPACE): pause, step, reset,
/// resume or stop it, or restart, stop and start the components of a `tutti run`.
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Examples:\n  tutti ctl state\n  tutti ctl pause\n  tutti ctl step 7 --json\n  tutti ctl speed 4\n  tutti ctl seek 12.5   # a replay: on from the recorded step at 12.5 s\n  tutti ctl reset\n  tutti ctl save warm.tutti-checkpoint\n  tutti ctl restore warm.tutti-checkpoint\n  tutti ctl save run.tutti-checkpoint --skip-stateless\n  tutti ctl reset state\n  tutti ctl resume\n  tutti ctl restart ctrl\n  tutti ctl signal uav3 USR1\n  tutti ctl stop\n  TUTTI_NAMESPACE=lab2 tutti ctl state --json\n\nWhile paused, no step is made and no participant times out, however long the pause; `step N`\nmakes exactly N steps and pauses again; `speed X` steps at X times real time from now on; `seek T` takes a replay (tutti replay) to its recorded step at T s. `save FILE` writes a checkpoint of the run (values and every\ncomponent's state) at the next step boundary, `restore FILE` puts one back, `reset state` goes back to\nthe run's step 0, states included (docs/run.md, Checkpoints). `stop` with no component ends the run and waits\nuntil it is gone. Only the user who started the run may control it. See docs/run.md."
)]
pub struct Args {
    /// state, pause, resume, step N, speed X, seek T, reset (or reset state), save FILE, restore FILE, stop,
    /// stop/restart/start COMPONENT, or signal COMPONENT SIGNAL (USR1, USR2, TERM, INT, HUP, …)
    #[arg(value_name = "COMMAND", required = true, num_args = 1..=3)]
    command: Vec<String>,
    /// Print the run's state after the command as one JSON object.
    #[arg(long)]
    json: bool,
    /// save: leave out the components that keep no state (the checkpoint names them)
    /// instead of failing.
    #[arg(long)]
    skip_stateless: bool,
    /// Namespace of the run (default: TUTTI_NAMESPACE, else tutti).
    #[arg(long)]
    namespace: Option<String>,
    /// Longest wait for the run's answer (a `step N` answers once its N steps are made).
    #[arg(long, default_value = "30s", value_parser = parse_duration)]
    timeout: Duration,
}

/// The request that `words` ask for (`skip_stateless`: `save`'s flag).
fn request(words: &[String], skip_stateless: bool) -> anyhow::Result<Request> {
    let arg = words.get(1).map(String::as_str);
    if words[0] == "signal" {
        return match (arg, words.get(2)) {
            (Some(name), Some(sig)) => {
                tutti_host::control::parse_signal(sig).map_err(|e| anyhow::anyhow!("signal: {e}"))?;
                Ok(Request::Signal { name: name.to_string(), signal: sig.clone() })
            }
            _ => Err(anyhow::anyhow!("signal needs a COMPONENT and a SIGNAL, like `tutti ctl signal uav3 USR1`")),
        };
    }
    if let Some(extra) = words.get(2) {
        return Err(anyhow::anyhow!("{}: one argument at most (got '{extra}' too)", words[0]));
    }
    let component = |action| match arg {
        Some(name) => Ok(Request::Component { action, name: name.to_string() }),
        None => Err(anyhow::anyhow!("{} needs a COMPONENT", words[0])),
    };
    let alone = |r: Request| match arg {
        None => Ok(r),
        Some(a) => Err(anyhow::anyhow!("{} takes no argument (got '{a}')", words[0])),
    };
    match words[0].as_str() {
        "state" => alone(Request::State),
        "pause" => alone(Request::Pause),
        "resume" => alone(Request::Resume),
        "reset" => match arg {
            None => Ok(Request::Reset),
            Some("state") => Ok(Request::ResetState),
            Some(a) => Err(anyhow::anyhow!("reset takes no argument or `state` (got '{a}')")),
        },
        "save" | "restore" => {
            let Some(file) = arg else { return Err(anyhow::anyhow!("{} needs a FILE", words[0])) };
            // The run's process reads and writes it: its working directory may be another.
            let path = std::path::absolute(file).map_err(|e| anyhow::anyhow!("{file}: {e}"))?;
            let path = path.display().to_string();
            Ok(match words[0].as_str() {
                "save" => Request::Save { path, skip_stateless },
                _ => Request::Restore { path },
            })
        }
        "step" => match arg.map(str::parse::<u64>) {
            Some(Ok(n)) if n > 0 => Ok(Request::Step { n }),
            Some(_) => Err(anyhow::anyhow!("step N: '{}' is not a number of steps above 0", arg.unwrap_or_default())),
            None => Err(anyhow::anyhow!("step needs N, the number of steps")),
        },
        "speed" => match arg.map(str::parse::<f64>) {
            Some(Ok(factor)) if factor.is_finite() && factor > 0.0 => Ok(Request::Speed { factor }),
            Some(_) => Err(anyhow::anyhow!("speed X: '{}' is not a factor above 0", arg.unwrap_or_default())),
            None => Err(anyhow::anyhow!("speed needs X, the factor of real time (2: twice as fast)")),
        },
        "seek" => match arg.map(str::parse::<f64>) {
            Some(Ok(time)) if time.is_finite() && time >= 0.0 => Ok(Request::Seek { time }),
            Some(_) => Err(anyhow::anyhow!("seek T: '{}' is not a simulated time in seconds", arg.unwrap_or_default())),
            None => Err(anyhow::anyhow!("seek needs T, the simulated time (s) of the recorded step to go on from")),
        },
        "stop" if arg.is_none() => Ok(Request::Stop),
        "stop" => component(ComponentAction::Stop),
        "restart" => component(ComponentAction::Restart),
        "start" => component(ComponentAction::Start),
        other => Err(anyhow::anyhow!(
            "unknown command '{other}': expected state, pause, resume, step N, speed X, seek T, reset [state], save FILE, restore FILE, stop [COMPONENT], restart COMPONENT, start COMPONENT or signal COMPONENT SIGNAL"
        )),
    }
}

pub fn run(args: Args) -> CliResult {
    let request = request(&args.command, args.skip_stateless).map_err(|e| Failure::invalid(e.context("tutti ctl")))?;
    let ns = args.namespace.clone().unwrap_or_else(namespace_from_env);
    let checkpoint = matches!(request, Request::Save { .. } | Request::Restore { .. } | Request::ResetState);
    let failed = |e: ControlError| match e {
        // A checkpoint refused (another DDF's, damaged, a component without a state): exit 2.
        ControlError::Refused(_) if checkpoint => Failure::invalid(anyhow::Error::new(e)),
        ControlError::Refused(_) | ControlError::NoRun { .. } => Failure::from(anyhow::Error::new(e)),
        e => Failure::from(anyhow::Error::new(e).context(format!("tutti ctl {}", args.command.join(" ")))),
    };
    let mut client = ControlClient::connect(&ns, args.timeout).map_err(failed)?;
    let status = client.request(&request).map_err(failed)?;
    if request == Request::Stop {
        wait_gone(&ns, args.timeout)?;
    }
    print(&status, args.json);
    Ok(())
}

/// Waits until the run of `ns` has ended (its control socket is gone).
fn wait_gone(ns: &str, timeout: Duration) -> CliResult {
    let end = Instant::now() + timeout;
    while tutti_host::control::socket_path(ns).exists() {
        if Instant::now() >= end {
            return Err(anyhow::anyhow!(
                "the run of namespace '{ns}' was asked to stop but still runs after {timeout:?}"
            )
            .into());
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    Ok(())
}

fn print(s: &RunStatus, json: bool) {
    if json {
        println!("{}", serde_json::to_string(s).unwrap_or_default());
        return;
    }
    println!(
        "{}  step {}  sim {:.6} s  (namespace {}, pid {})",
        s.state.name(),
        s.step,
        s.sim_time,
        s.namespace,
        s.pid
    );
    for c in &s.components {
        let pid = c.pid.map(|p| format!("pid {p}")).unwrap_or_else(|| "no process".into());
        println!("  {:<16} {:<10} {pid}  restarts {}", c.name, c.state, c.restarts);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn words(s: &str) -> Vec<String> {
        s.split_whitespace().map(String::from).collect()
    }

    #[test]
    fn commands_parse_and_mistakes_say_what_is_expected() {
        let err = |s: &str| request(&words(s), false).unwrap_err().to_string();
        assert_eq!(request(&words("step 7"), false).unwrap(), Request::Step { n: 7 });
        assert_eq!(request(&words("speed 2.5"), false).unwrap(), Request::Speed { factor: 2.5 });
        assert_eq!(request(&words("seek 1.5"), false).unwrap(), Request::Seek { time: 1.5 });
        for bad in ["speed", "speed 0", "speed -1", "speed inf", "speed fast", "seek", "seek -1", "seek later"] {
            assert!(request(&words(bad), false).is_err(), "{bad}");
        }
        assert_eq!(request(&words("stop"), false).unwrap(), Request::Stop);
        assert_eq!(
            request(&words("stop ctrl"), false).unwrap(),
            Request::Component { action: ComponentAction::Stop, name: "ctrl".into() }
        );
        assert!(err("step 0").contains("above 0"));
        assert!(err("step").contains("needs N"));
        assert!(err("restart").contains("needs a COMPONENT"));
        assert!(err("pause now").contains("takes no argument"));
        assert!(err("jump").contains("unknown command 'jump'"));
        assert_eq!(
            request(&words("signal uav3 USR1"), false).unwrap(),
            Request::Signal { name: "uav3".into(), signal: "USR1".into() }
        );
        assert!(err("signal uav3").contains("needs a COMPONENT and a SIGNAL"));
        assert!(err("signal uav3 USR9").contains("unknown signal 'USR9'"));
        assert!(err("restart a b").contains("one argument at most"));
    }
}
