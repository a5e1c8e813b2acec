//! A [`Host`]'s checkpoints (docs/run.md, "Checkpoints"): taken at a step boundary, put
//! back, saved every so many steps, and the control plane's `save`, `restore` and
//! `reset_state`.

use std::sync::atomic::Ordering;

use tutti_core::shm::{StateAnswer, StateConnection, StateRequest};

use super::{Host, Report};
use crate::checkpoint::{Checkpoint, CheckpointError, ComponentState, DomainState, Skipped};
use crate::control::{Refusal, Request};

/// One domain's components' states, by name, as a save collected them (and whether each is
/// a link's, [`ComponentState::remote`]).
type Saved = Vec<(String, Vec<u8>, bool)>;

impl Host {
    /// The checkpoint of step 0, which `ResetState` goes back to. When it cannot be taken
    /// the run goes on without one; it says why where a component keeps a state (its user
    /// meant to have one), and a refused `ResetState` says why always.
    pub(super) fn take_initial(&mut self, on_report: &mut dyn FnMut(Report)) {
        let opted_in = self.fw.domains.iter().any(|d| d.state_connections().iter().any(|c| c.keeps_state));
        let initial = self.checkpoint(false);
        match &initial {
            Ok(_) => {
                if let Some(ctl) = &self.control {
                    ctl.shared.state_reset.store(true, Ordering::Release);
                }
            }
            Err(why) if opted_in => on_report(Report::NoStateReset(why.to_string())),
            Err(_) => {}
        }
        self.initial = Some(initial);
    }

    /// A checkpoint of the run as it stands, at a step boundary (between two steps, or
    /// before the first): the framework's time, every domain's sets and each component's
    /// state. Fails naming every component that keeps no state, unless `skip_stateless`
    /// (they are then named in the checkpoint); components declared stateless
    /// ([`HostOptions::stateless`](super::HostOptions::stateless)) are always left out that way.
    pub fn checkpoint(&mut self, skip_stateless: bool) -> Result<Checkpoint, CheckpointError> {
        let conns: Vec<Vec<StateConnection>> = self.fw.domains.iter().map(|d| d.state_connections()).collect();
        // The answers on their way across a link with a lookahead are kept by the gateway's
        // connection (a remote one that keeps a state); without them a restored run would
        // differ.
        for (d, list) in self.fw.domains.iter().zip(&conns) {
            if let Some(lookahead) = d.lookahead().filter(|_| !list.iter().any(|c| c.remote)) {
                return Err(CheckpointError::Lookahead { domain: d.info().name.clone(), lookahead });
            }
        }
        let mut skipped = Vec::new();
        let mut missing = Vec::new();
        let mut asked: Vec<Vec<(&StateConnection, &[u8])>> = Vec::with_capacity(conns.len());
        for (d, list) in self.fw.domains.iter().zip(&conns) {
            let domain = &d.info().name;
            let mut mine = Vec::new();
            for (i, c) in list.iter().enumerate() {
                if list[..i].iter().any(|o| o.name == c.name) {
                    return Err(CheckpointError::SameName { domain: domain.clone(), name: c.name.clone() });
                }
                let skip = |why: &str| Skipped { domain: domain.clone(), name: c.name.clone(), why: why.into() };
                if c.remote {
                    mine.push((c, &[][..]));
                } else if self.opts.stateless.contains(&c.name) {
                    skipped.push(skip("stateless"));
                } else if c.keeps_state {
                    mine.push((c, &[][..]));
                } else if skip_stateless {
                    skipped.push(skip("keeps no state"));
                } else {
                    missing.push((domain.clone(), c.name.clone()));
                }
            }
            asked.push(mine);
        }
        if !missing.is_empty() {
            return Err(CheckpointError::KeepsNoState(missing));
        }
        let answers = self.exchange(StateRequest::Save, &asked)?;
        let mut components = Vec::new();
        for (d, saved) in self.fw.domains.iter().zip(answers) {
            for (name, state, remote) in saved {
                components.push(ComponentState { domain: d.info().name.clone(), name, state, remote });
            }
        }
        let domains = self
            .fw
            .domains
            .iter()
            .zip(&self.publish)
            .zip(&conns)
            .map(|((d, publish), list)| DomainState {
                name: d.info().name.clone(),
                layout_hash: d.info().layout_hash,
                publish: publish.clone(),
                subscribe: d.subscribe().to_vec(),
                last_publish: d.last_publish().map(<[u8]>::to_vec),
                seeded: d.seeded(),
                due: list
                    .iter()
                    .filter(|c| d.info().flags.event && !c.remote)
                    .map(|c| (c.name.clone(), c.due_index))
                    .collect(),
            })
            .collect();
        Ok(Checkpoint {
            ddf: self.opts.ddf_name.clone(),
            step_seconds: self.opts.step.as_secs_f64(),
            next_index: self.ticker.next_k(),
            steps: self.steps,
            domains,
            components,
            skipped,
        })
    }

    /// Asks the components for their states and collects the answers (the step timeout):
    /// each domain's components by name, with the state each saved (nothing for a restore).
    /// A component that failed or did not answer fails the whole, with its words.
    fn exchange(
        &self,
        kind: StateRequest,
        asked: &[Vec<(&StateConnection, &[u8])>],
    ) -> Result<Vec<Saved>, CheckpointError> {
        let answers = self
            .fw
            .exchange_states(kind, asked, self.opts.timeout)
            .map_err(|source| CheckpointError::Domain { domain: self.opts.ddf_name.clone(), source })?;
        let what = match kind {
            StateRequest::Save => "save",
            StateRequest::Restore => "restore",
        };
        let mut out = Vec::with_capacity(answers.len());
        for ((d, mine), answers) in self.fw.domains.iter().zip(asked).zip(answers) {
            let mut got = Vec::new();
            for ((c, _), answer) in mine.iter().zip(answers) {
                let why = match answer {
                    StateAnswer::Saved(state) => {
                        got.push((c.name.clone(), state, c.remote));
                        continue;
                    }
                    StateAnswer::Restored => continue,
                    StateAnswer::Failed(why) => why,
                    StateAnswer::NoAnswer => format!("no answer within {:?}", self.opts.timeout),
                };
                return Err(CheckpointError::Component {
                    domain: d.info().name.clone(),
                    name: c.name.clone(),
                    what,
                    why,
                });
            }
            out.push(got);
        }
        Ok(out)
    }

    /// Puts checkpoint `c` back at a step boundary: every component that kept a state takes
    /// it back, every domain gets its sets back, and the run goes on from the checkpoint's
    /// step. Checked first, as a whole: a checkpoint of another DDF, or one whose components
    /// are not all in this run, is refused before anything changes.
    pub fn restore(&mut self, c: &Checkpoint) -> Result<(), CheckpointError> {
        let what = format!("the checkpoint of {}", c.ddf);
        let layouts = self.fw.domains.iter().map(|d| {
            let i = d.info();
            (i.name.as_str(), i.layout_hash, i.publish.size as usize, i.subscribe.size as usize)
        });
        c.check_layouts(layouts, &what)?;
        if (c.step_seconds - self.opts.step.as_secs_f64()).abs() > 1e-12 * c.step_seconds {
            return Err(CheckpointError::Mismatch(format!(
                "the checkpoint's step is {} s, this run's {} s",
                c.step_seconds,
                self.opts.step.as_secs_f64()
            )));
        }
        let index: std::collections::HashMap<&str, usize> =
            self.fw.domains.iter().enumerate().map(|(i, d)| (d.info().name.as_str(), i)).collect();
        let conns = self.connections_for(c, &index);
        let mut asked: Vec<Vec<(&StateConnection, &[u8])>> = vec![Vec::new(); conns.len()];
        for s in &c.components {
            let d = index.get(s.domain.as_str()).copied();
            let found = d.and_then(|d| find(&conns[d], s).map(|x| (d, x)));
            match found {
                Some((d, x)) if x.keeps_state => asked[d].push((x, &s.state)),
                Some(_) => {
                    return Err(CheckpointError::Mismatch(format!(
                        "component '{}' of domain '{}' keeps no state in this run",
                        s.name, s.domain
                    )))
                }
                None if s.remote => {
                    return Err(CheckpointError::Mismatch(format!(
                        "domain '{}' was joined to another site ('{}'), and no link of this run joined it within {:?}",
                        s.domain, s.name, self.opts.timeout
                    )))
                }
                None => {
                    return Err(CheckpointError::Mismatch(format!(
                        "component '{}' of domain '{}' is in the checkpoint, not connected in this run",
                        s.name, s.domain
                    )))
                }
            }
        }
        for (i, (d, list)) in self.fw.domains.iter().zip(&conns).enumerate() {
            let domain = &d.info().name;
            for x in list.iter().filter(|x| x.keeps_state) {
                // Found for one of the checkpoint's states above.
                let saved = asked[i].iter().any(|(y, _)| std::ptr::eq(*y, x));
                if x.remote && !saved {
                    // A link that had not joined at the checkpoint: it joins again at the next
                    // step (no state: nothing on its way).
                    asked[i].push((x, &[][..]));
                    continue;
                }
                let skipped = c.skipped.iter().any(|s| &s.domain == domain && s.name == x.name);
                if !saved && !skipped && !self.opts.stateless.contains(&x.name) {
                    return Err(CheckpointError::Mismatch(format!(
                        "component '{}' of domain '{domain}' keeps a state and the checkpoint has none for it",
                        x.name
                    )));
                }
            }
        }
        self.exchange(StateRequest::Restore, &asked)?;
        for (i, d) in self.fw.domains.iter_mut().enumerate() {
            let Some(saved) = c.domain(i, &d.info().name) else { continue };
            self.publish[i].copy_from_slice(&saved.publish);
            d.restore_sets(&saved.subscribe, saved.last_publish.as_deref(), saved.seeded)
                .map_err(|source| CheckpointError::Domain { domain: saved.name.clone(), source })?;
            for x in &conns[i] {
                if let Some((_, index)) = saved.due.iter().find(|(n, _)| *n == x.name) {
                    d.set_due_index(x.slot, *index);
                }
            }
        }
        self.ticker.restart_at(c.next_index);
        self.steps = c.steps;
        let now = self.last_sim();
        self.fw.domains.iter().for_each(|d| d.reset_time(now));
        self.publish_state(self.state(), now);
        Ok(())
    }

    /// The connections of every domain (by `index`) that checkpoint `c` restores; waits (the
    /// step timeout at most) for the links to other sites `c` holds to connect: in a new run
    /// the gateway joins them once it has found the other site.
    fn connections_for(
        &self,
        c: &Checkpoint,
        index: &std::collections::HashMap<&str, usize>,
    ) -> Vec<Vec<StateConnection>> {
        let deadline = std::time::Instant::now() + self.opts.timeout;
        loop {
            let conns: Vec<Vec<StateConnection>> = self.fw.domains.iter().map(|d| d.state_connections()).collect();
            let waiting = c
                .components
                .iter()
                .filter(|s| s.remote)
                .any(|s| index.get(s.domain.as_str()).is_some_and(|&d| find(&conns[d], s).is_none()));
            if !waiting || std::time::Instant::now() >= deadline {
                return conns;
            }
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
    }

    /// A periodic checkpoint, if this step is one's.
    pub(super) fn periodic_checkpoint(&mut self, on_report: &mut dyn FnMut(Report)) {
        let Some(p) = self.opts.checkpoint.clone() else { return };
        if p.every == 0 || self.steps % p.every != 0 {
            return;
        }
        let path = p.dir.join(format!("step-{:09}.{}", self.steps, crate::checkpoint::EXTENSION));
        let saved = std::fs::create_dir_all(&p.dir)
            .map_err(|source| CheckpointError::Io { path: p.dir.clone(), source })
            .and_then(|()| self.checkpoint(false))
            .and_then(|c| c.write(&path));
        match saved {
            Ok(()) => {
                on_report(Report::Saved { path, step: self.steps });
                if p.keep > 0 {
                    crate::checkpoint::keep_newest(&p.dir, p.keep);
                }
            }
            Err(e) => on_report(Report::CheckpointFailed(e.to_string())),
        }
    }

    /// Carries out a checkpoint command at this step boundary.
    pub(super) fn checkpoint_command(&mut self, request: &Request) -> Result<(), Refusal> {
        let refuse = |e: CheckpointError| Refusal(e.to_string());
        match request {
            Request::Save { path, skip_stateless } => {
                let c = self.checkpoint(*skip_stateless).map_err(refuse)?;
                c.write(std::path::Path::new(path)).map_err(refuse)
            }
            Request::Restore { path } => {
                let c = Checkpoint::read(std::path::Path::new(path)).map_err(refuse)?;
                self.restore(&c).map_err(refuse)
            }
            Request::ResetState => {
                let initial = self.initial.take();
                let r = match &initial {
                    Some(Ok(c)) => self.restore(c).map_err(refuse),
                    Some(Err(why)) => {
                        Err(Refusal(format!("reset_state: this run has no checkpoint of its step 0: {why}")))
                    }
                    None => Err(Refusal("reset_state: the run has not started".into())),
                };
                self.initial = initial;
                r
            }
            _ => Ok(()),
        }
    }
}

/// The connection of `list` that saved state `s`: a component by its name; a link to
/// another site by its name, else the one link of its domain (the name shows the other
/// site's gateway, which has another identity once that site started again).
fn find<'a>(list: &'a [StateConnection], s: &ComponentState) -> Option<&'a StateConnection> {
    list.iter().find(|x| x.name == s.name && x.remote == s.remote).or_else(|| {
        let mut links = list.iter().filter(|x| s.remote && x.remote);
        match (links.next(), links.next()) {
            (Some(x), None) => Some(x),
            _ => None,
        }
    })
}
