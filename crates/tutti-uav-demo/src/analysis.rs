//! The demo's results: its CSV files, read back, and the checks of the run (the paper's
//! claims about Figures 5 and 6, made testable).
//!
//! Files in the output directory:
//! * `framework.csv`: `step,sim_time,wall_s`, then per UAV N `uavN_elevation` and `uavN_time`
//!   (SUBSCRIBE Elevation and Time as the framework read them this step), `uavN_altitude_pub`
//!   (PUBLISH Altitude of this step: the elevation read at the step before) and
//!   `uavN_connections`;
//! * `uavN.csv`: `time_s,latitude_deg,longitude_deg,altitude_m,heading_deg,airspeed_mps,connected`, the state the UAV model computed;
//! * `connections.csv`: `sim_time,wall_s,uav1..uav4`, the connection counts the monitoring
//!   script saw; `events.csv`: `sim_time,uav,event`, the requests it sent;
//! * `c_readerN.csv`: `time,altitude,connections`, what the C component N read;
//! * `altitude_filter.csv`: `step,sim_time,elevation,altitude,climb_rate,steps,connections`,
//!   the FMU component's domain: UAV 1's elevation published, the FMU's answer read.

use std::path::Path;

use anyhow::Context;

use crate::scenario::{Action, Scenario, FMU_TAU, UAVS};

/// A CSV file of numbers with a header line.
#[derive(Debug, Clone, Default)]
pub struct Table {
    pub header: Vec<String>,
    pub rows: Vec<Vec<f64>>,
}

impl Table {
    /// Parses CSV text; non-numeric fields become NaN, a truncated last line is dropped.
    pub fn parse(text: &str) -> Table {
        let mut lines = text.lines();
        let header: Vec<String> = lines.next().unwrap_or("").split(',').map(|s| s.trim().to_string()).collect();
        let rows = lines
            .filter(|l| !l.trim().is_empty())
            .map(|l| l.split(',').map(|f| f.trim().parse::<f64>().unwrap_or(f64::NAN)).collect::<Vec<_>>())
            .filter(|r| r.len() == header.len())
            .collect();
        Table { header, rows }
    }

    pub fn read(path: &Path) -> anyhow::Result<Table> {
        let text = std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
        Ok(Table::parse(&text))
    }

    /// Column `name`, or an empty vector.
    pub fn col(&self, name: &str) -> Vec<f64> {
        match self.header.iter().position(|h| h == name) {
            Some(i) => self.rows.iter().map(|r| r[i]).collect(),
            None => Vec::new(),
        }
    }
}

/// Everything a run wrote.
#[derive(Debug, Clone, Default)]
pub struct RunData {
    pub framework: Table,
    pub uavs: Vec<Table>,
    pub connections: Table,
    pub events: Table,
    pub c_readers: Vec<Table>,
    /// The FMU component's domain (`altitude_filter.csv`).
    pub fmu: Table,
}

impl RunData {
    /// Reads the files of `dir`; a missing file is an empty table (and fails its checks).
    pub fn load(dir: &Path, scenario: &Scenario) -> RunData {
        let read = |name: &str| Table::read(&dir.join(name)).unwrap_or_default();
        RunData {
            framework: read("framework.csv"),
            uavs: (1..=UAVS).map(|i| read(&format!("uav{i}.csv"))).collect(),
            connections: read("connections.csv"),
            events: read("events.csv"),
            c_readers: (1..=scenario.c_readers.len()).map(|i| read(&format!("c_reader{i}.csv"))).collect(),
            fmu: read("altitude_filter.csv"),
        }
    }
}

/// One check of the run.
#[derive(Debug, Clone, PartialEq)]
pub struct Check {
    pub name: String,
    pub pass: bool,
    pub detail: String,
}

impl Check {
    fn new(name: String, pass: bool, detail: String) -> Check {
        Check { name, pass, detail }
    }
}

/// Linear interpolation of `(xs, ys)` at `x` (xs increasing); `None` outside.
pub fn interp(xs: &[f64], ys: &[f64], x: f64) -> Option<f64> {
    if xs.is_empty() || x < xs[0] - 1e-9 || x > xs[xs.len() - 1] + 1e-9 {
        return None;
    }
    let i = xs.partition_point(|&v| v < x);
    if i == 0 {
        return Some(ys[0]);
    }
    if i >= xs.len() {
        return Some(ys[xs.len() - 1]);
    }
    let (x0, x1) = (xs[i - 1], xs[i]);
    if x1 - x0 <= 0.0 {
        return Some(ys[i]);
    }
    Some(ys[i - 1] + (ys[i] - ys[i - 1]) * (x - x0) / (x1 - x0))
}

/// The disconnected stretches of a UAV log: `(first disconnected time, time of the first
/// row connected again)`, the second infinite when it stayed disconnected.
pub fn observed_windows(uav: &Table) -> Vec<(f64, f64)> {
    let (t, c) = (uav.col("time_s"), uav.col("connected"));
    let mut out = Vec::new();
    let mut open: Option<f64> = None;
    for (&t, &c) in t.iter().zip(&c) {
        match (c >= 0.5, open) {
            (false, None) => open = Some(t),
            (true, Some(from)) => {
                out.push((from, t));
                open = None;
            }
            _ => {}
        }
    }
    if let Some(from) = open {
        out.push((from, f64::INFINITY));
    }
    out
}

/// Largest minus smallest of `v` (0 when empty).
fn range(v: &[f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.iter().copied().fold(f64::NEG_INFINITY, f64::max) - v.iter().copied().fold(f64::INFINITY, f64::min)
}

/// The framework's rows as `(sim_time, value of column)`, for `col`.
fn series(fw: &Table, col: &str) -> (Vec<f64>, Vec<f64>) {
    (fw.col("sim_time"), fw.col(col))
}

/// All checks of a run with simulated step `step` (s).
pub fn run_checks(s: &Scenario, d: &RunData, step: f64) -> Vec<Check> {
    let mut out = Vec::new();
    let fw_ok = !d.framework.rows.is_empty();
    out.push(Check::new(
        "the framework stepped and recorded".into(),
        fw_ok,
        format!("{} steps in framework.csv", d.framework.rows.len()),
    ));
    for uav in 1..=UAVS {
        let scripted = s.windows(uav);
        if scripted.is_empty() {
            continue;
        }
        let seen = d.uavs.get(uav - 1).map(observed_windows).unwrap_or_default();
        for &(a, b) in &scripted {
            let found = seen.iter().copied().find(|&(x, _)| (x - a).abs() <= 2.0);
            out.push(held_level(d, uav, (a, b), found, step));
            if b.is_finite() {
                out.push(merged(d, uav, (a, b), found, &seen, step));
            }
        }
    }
    out.push(requests_sent(s, d));
    for (j, &start) in s.c_readers.iter().enumerate() {
        out.push(c_reader(d, s.c_domain_uav, j, start));
    }
    out.push(connection_counts(s, d));
    out.push(fmu_filter(d, step));
    out
}

/// The FMU component (AltitudeFilter through `tutti fmu run`) answered the steps in lock-step
/// with UAV 1's elevation filtered as its model says: each answer is recomputed here from the
/// elevation published at that step (from its third step on, when its step size is the
/// simulated step; the first ones use the wall-clock period, see docs/fmu.md).
fn fmu_filter(d: &RunData, step: f64) -> Check {
    let name = "the FMU component filtered UAV1's elevation at every step".to_string();
    let (elev, alt, n) = (d.fmu.col("elevation"), d.fmu.col("altitude"), d.fmu.col("steps"));
    if n.iter().all(|&k| k.is_nan() || k < 1.0) {
        return Check::new(name, false, "altitude_filter.csv: the FMU never answered".into());
    }
    let a = (step / FMU_TAU).min(1.0);
    let (mut judged, mut skipped, mut worst) = (0usize, 0usize, 0.0f64);
    for i in 1..n.len() {
        if n[i - 1] < 2.0 {
            continue;
        }
        if n[i] != n[i - 1] + 1.0 {
            skipped += 1;
            continue;
        }
        let want = alt[i - 1] + a * (elev[i] - alt[i - 1]);
        worst = worst.max((alt[i] - want).abs());
        judged += 1;
    }
    let pass = judged >= 10 && skipped * 10 <= judged && worst <= 1e-6;
    Check::new(
        name,
        pass,
        format!(
            "{judged} answers recomputed (max difference {worst:.1e} m), {skipped} steps not answered in lock-step"
        ),
    )
}

/// The monitoring script sent every scripted request, within a second of its time.
fn requests_sent(s: &Scenario, d: &RunData) -> Check {
    let name = "the monitoring script sent every scripted disconnect / connect request on time".to_string();
    let (t, uav, connect) = (d.events.col("sim_time"), d.events.col("uav"), d.events.col("connect"));
    let mut problems = Vec::new();
    for e in &s.events {
        let want = f64::from(u8::from(e.action == Action::Connect));
        let sent = (0..t.len()).find(|&i| uav[i] == e.uav as f64 && connect[i] == want).map(|i| t[i]);
        match sent {
            Some(x) if (x - e.t).abs() <= 1.0 => {}
            Some(x) => problems.push(format!("{e} sent at {x:.2} s")),
            None => problems.push(format!("{e} never sent")),
        }
    }
    let detail =
        if problems.is_empty() { format!("{} requests sent as scripted", s.events.len()) } else { problems.join("; ") };
    Check::new(name, problems.is_empty(), detail)
}

fn held_level(d: &RunData, uav: usize, (a, b): (f64, f64), found: Option<(f64, f64)>, step: f64) -> Check {
    let name = format!("UAV{uav}: the framework's altitude holds level while disconnected ({a:.0}-{b:.0} s)");
    let Some((x, y)) = found else {
        return Check::new(name, false, format!("uav{uav}.csv shows no disconnection near {a:.1} s"));
    };
    let (t, e) = series(&d.framework, &format!("uav{uav}_elevation"));
    let y = y.min(t.last().copied().unwrap_or(0.0));
    let held: Vec<f64> =
        t.iter().zip(&e).filter(|(&t, _)| t >= x + 2.0 * step && t <= y - step).map(|(_, &v)| v).collect();
    if held.len() < 3 {
        return Check::new(name, false, format!("only {} framework steps in the window {x:.2}-{y:.2} s", held.len()));
    }
    let spread = range(&held);
    let table = &d.uavs[uav - 1];
    let (ut, ua) = (table.col("time_s"), table.col("altitude_m"));
    let moved: Vec<f64> = ut.iter().zip(&ua).filter(|(&t, _)| t >= x && t <= y).map(|(_, &v)| v).collect();
    let model_range = range(&moved);
    Check::new(
        name,
        spread < 1e-9,
        format!(
            "disconnected {x:.2}-{y:.2} s: framework read {:.2} m over {} steps (spread {spread:.3} m) while the model moved {model_range:.1} m",
            held[0],
            held.len()
        ),
    )
}

fn merged(
    d: &RunData,
    uav: usize,
    (_, b): (f64, f64),
    found: Option<(f64, f64)>,
    seen: &[(f64, f64)],
    step: f64,
) -> Check {
    let name = format!("UAV{uav}: the framework's altitude merges with the model's after reconnection ({b:.0} s)");
    let Some((_, y)) = found.filter(|w| w.1.is_finite()) else {
        return Check::new(name, false, "no reconnection in the UAV's log".into());
    };
    if (y - b).abs() > 2.0 {
        return Check::new(name, false, format!("reconnected at {y:.2} s, scripted {b:.1} s"));
    }
    let until = seen.iter().map(|w| w.0).find(|&x| x > y).unwrap_or(f64::INFINITY);
    let fw = &d.framework;
    let (t, e, ut) = (fw.col("sim_time"), fw.col(&format!("uav{uav}_elevation")), fw.col(&format!("uav{uav}_time")));
    let table = &d.uavs[uav - 1];
    let (mt, ma) = (table.col("time_s"), table.col("altitude_m"));
    let (mut n, mut worst, mut worst_clock) = (0usize, 0.0f64, 0.0f64);
    for i in 0..t.len() {
        if t[i] < y + 1.0 || t[i] >= until - step {
            continue;
        }
        let Some(model) = interp(&mt, &ma, ut[i]) else { continue };
        n += 1;
        worst = worst.max((e[i] - model).abs());
        worst_clock = worst_clock.max((ut[i] - t[i]).abs());
    }
    let pass = n >= 3 && worst < 0.01 && worst_clock <= step + 1e-6;
    Check::new(
        name,
        pass,
        format!(
            "reconnected at {y:.2} s; over {n} steps after it the framework read the model's altitude within {worst:.4} m, clocks within {worst_clock:.3} s"
        ),
    )
}

fn c_reader(d: &RunData, uav: usize, j: usize, start: f64) -> Check {
    let name = format!(
        "C component {} (connects at {start:.0} s) read every UAV{uav} altitude the framework published",
        j + 1
    );
    let Some(r) = d.c_readers.get(j).filter(|r| !r.rows.is_empty()) else {
        return Check::new(name, false, format!("c_reader{}.csv has no rows", j + 1));
    };
    let (rt, ra) = (r.col("time"), r.col("altitude"));
    let fw = &d.framework;
    let (ft, fa) = (fw.col("sim_time"), fw.col(&format!("uav{uav}_altitude_pub")));
    let first = rt[0];
    let last = rt[rt.len() - 1];
    let mut problems = Vec::new();
    if first < start - 1e-6 || first > start + 3.0 {
        problems.push(format!("first read at {first:.2} s"));
    }
    // Every framework step between its first and last read, once, with the published value.
    let expected: Vec<(f64, f64)> =
        ft.iter().zip(&fa).filter(|(&t, _)| t >= first - 1e-6 && t <= last + 1e-6).map(|(&t, &a)| (t, a)).collect();
    if expected.len() != rt.len() {
        problems.push(format!("{} reads for {} published steps", rt.len(), expected.len()));
    }
    let mismatched = expected
        .iter()
        .zip(rt.iter().zip(&ra))
        .filter(|((et, ea), (t, a))| (*et - *t).abs() > 1e-6 || (*ea - *a).abs() > 1e-9)
        .count();
    if mismatched > 0 {
        problems.push(format!("{mismatched} reads differ from what the framework published"));
    }
    let fw_last = ft.last().copied().unwrap_or(0.0);
    if last < fw_last - 1.0 {
        problems.push(format!("stopped reading at {last:.2} s, the framework ran to {fw_last:.2} s"));
    }
    let detail = if problems.is_empty() {
        format!("{} steps read, {first:.2}-{last:.2} s, all equal to the published Altitude", rt.len())
    } else {
        problems.join("; ")
    };
    Check::new(name, problems.is_empty(), detail)
}

/// Samples closer than this to a scripted change (simulated s) are not judged.
pub const COUNT_TOLERANCE: f64 = 2.0;

fn connection_counts(s: &Scenario, d: &RunData) -> Check {
    let name = "connection counts per domain follow the script".to_string();
    let c = &d.connections;
    let t = c.col("sim_time");
    if t.is_empty() {
        return Check::new(name, false, "connections.csv has no rows".into());
    }
    let mut judged = 0usize;
    let mut wrong = Vec::new();
    let mut seen_levels = 0usize;
    let mut want_levels = 0usize;
    for uav in 1..=UAVS {
        let counts = c.col(&format!("uav{uav}"));
        let changes = s.change_times(uav);
        // Each scripted level (between changes) must be seen at least once.
        let mut bounds = vec![0.0];
        bounds.extend(&changes);
        bounds.push(s.duration);
        for w in bounds.windows(2) {
            let (a, b) = (w[0] + COUNT_TOLERANCE, w[1] - COUNT_TOLERANCE);
            if b <= a {
                continue;
            }
            want_levels += 1;
            if t.iter().any(|&x| x >= a && x <= b) {
                seen_levels += 1;
            }
        }
        for (&x, &n) in t.iter().zip(&counts) {
            if x > s.duration || changes.iter().any(|&ch| (x - ch).abs() < COUNT_TOLERANCE) {
                continue;
            }
            judged += 1;
            let want = s.expected_connections(uav, x);
            if n != f64::from(want) {
                wrong.push(format!("uav{uav} {n} at {x:.2} s (expected {want})"));
            }
        }
    }
    let pass = wrong.is_empty() && judged > 0 && seen_levels == want_levels;
    let mut detail =
        format!("{judged} samples judged, {} wrong, {seen_levels}/{want_levels} scripted levels seen", wrong.len());
    if !wrong.is_empty() {
        detail.push_str(": ");
        detail.push_str(&wrong.iter().take(5).cloned().collect::<Vec<_>>().join(", "));
    }
    Check::new(name, pass, detail)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A synthetic run of `s` that behaves exactly as scripted: a climbing UAV model, a
    /// framework that reads it except while disconnected, readers that read everything.
    fn perfect_run(s: &Scenario, step: f64) -> RunData {
        let alt = |uav: usize, t: f64| 300.0 + uav as f64 * 10.0 + 0.5 * t;
        let n = (s.duration / step).round() as usize;
        let mut fw = Table { header: vec!["step".into(), "sim_time".into(), "wall_s".into()], rows: vec![] };
        for i in 1..=UAVS {
            for c in ["elevation", "time", "altitude_pub", "connections"] {
                fw.header.push(format!("uav{i}_{c}"));
            }
        }
        let mut uavs: Vec<Table> = (0..UAVS)
            .map(|_| Table { header: crate::node::UAV_LOG_HEADER.split(',').map(String::from).collect(), rows: vec![] })
            .collect();
        let mut last_read = [0.0f64; UAVS];
        let mut last_time = [0.0f64; UAVS];
        let mut pubs = [0.0f64; UAVS];
        for k in 0..=n {
            let t = k as f64 * step;
            let mut row = vec![k as f64 + 1.0, t, t / 4.0];
            for i in 1..=UAVS {
                let away = s.windows(i).iter().any(|&(a, b)| t >= a && t < b);
                uavs[i - 1].rows.push(vec![t, 45.5, -73.6, alt(i, t), 90.0, 25.0, if away { 0.0 } else { 1.0 }]);
                pubs[i - 1] = last_read[i - 1];
                if !away {
                    last_read[i - 1] = alt(i, t);
                    last_time[i - 1] = t;
                }
                row.extend([last_read[i - 1], last_time[i - 1], pubs[i - 1], f64::from(s.expected_connections(i, t))]);
            }
            fw.rows.push(row);
        }
        let mut conns = Table { header: vec!["sim_time".into(), "wall_s".into()], rows: vec![] };
        conns.header.extend((1..=UAVS).map(|i| format!("uav{i}")));
        let mut t = 0.0;
        while t <= s.duration {
            let mut row = vec![t, t / 4.0];
            row.extend((1..=UAVS).map(|i| f64::from(s.expected_connections(i, t))));
            conns.rows.push(row);
            t += 0.25;
        }
        let c_readers = s
            .c_readers
            .iter()
            .map(|&start| {
                let pub_col =
                    fw.header.iter().position(|h| h == &format!("uav{}_altitude_pub", s.c_domain_uav)).unwrap();
                Table {
                    header: vec!["time".into(), "altitude".into(), "connections".into()],
                    rows: fw.rows.iter().filter(|r| r[1] >= start + 0.3).map(|r| vec![r[1], r[pub_col], 2.0]).collect(),
                }
            })
            .collect();
        let events = Table {
            header: vec!["sim_time".into(), "uav".into(), "connect".into(), "scheduled".into()],
            rows: s
                .events
                .iter()
                .map(|e| vec![e.t + 0.1, e.uav as f64, f64::from(u8::from(e.action == Action::Connect)), e.t])
                .collect(),
        };
        // The FMU answers every step from the first: its filter of UAV1's elevation read.
        let mut fmu = Table {
            header: ["step", "sim_time", "elevation", "altitude", "climb_rate", "steps", "connections"]
                .map(String::from)
                .to_vec(),
            rows: vec![],
        };
        let elev_col = fw.header.iter().position(|h| h == "uav1_elevation").unwrap();
        let a = (step / FMU_TAU).min(1.0);
        let mut filtered = f64::NAN;
        for (k, r) in fw.rows.iter().enumerate() {
            let e = r[elev_col];
            let before = if filtered.is_nan() { e } else { filtered };
            filtered = before + a * (e - before);
            fmu.rows.push(vec![r[0], r[1], e, filtered, (filtered - before) / step, k as f64 + 1.0, 1.0]);
        }
        RunData { framework: fw, uavs, connections: conns, events, c_readers, fmu }
    }

    #[test]
    fn csv_parsing_keeps_numbers_and_drops_torn_lines() {
        let t = Table::parse("a,b\n1,2\n3,x\n4\n");
        assert_eq!(t.rows.len(), 2);
        assert_eq!(t.col("a"), vec![1.0, 3.0]);
        assert!(t.col("b")[1].is_nan());
        assert!(t.col("zz").is_empty());
    }

    #[test]
    fn interpolation_and_windows() {
        assert_eq!(interp(&[0.0, 1.0], &[0.0, 10.0], 0.25), Some(2.5));
        assert_eq!(interp(&[0.0, 1.0], &[0.0, 10.0], 2.0), None);
        let u = Table::parse("time_s,altitude_m,connected\n0,1,1\n1,1,0\n2,1,0\n3,1,1\n4,1,0\n");
        assert_eq!(observed_windows(&u), vec![(1.0, 3.0), (4.0, f64::INFINITY)]);
    }

    #[test]
    fn a_run_as_scripted_passes_every_check() {
        let s = Scenario::short();
        let checks = run_checks(&s, &perfect_run(&s, 0.05), 0.05);
        // framework + (held + merged) × 2 UAVs + requests + 2 readers + counts.
        assert_eq!(checks.len(), 1 + 4 + 1 + 2 + 1 + 1, "{checks:#?}");
        assert!(checks.iter().all(|c| c.pass), "{checks:#?}");
    }

    #[test]
    fn each_kind_of_fault_fails_its_check() {
        let s = Scenario::short();
        let base = perfect_run(&s, 0.05);
        let failing = |d: &RunData| -> Vec<String> {
            run_checks(&s, d, 0.05).into_iter().filter(|c| !c.pass).map(|c| c.name).collect()
        };
        // The framework kept reading a moving altitude during UAV3's window.
        let mut d = base.clone();
        let col = d.framework.header.iter().position(|h| h == "uav3_elevation").unwrap();
        for r in d.framework.rows.iter_mut().filter(|r| r[1] > 14.0 && r[1] < 16.0) {
            r[col] += 1.0;
        }
        assert!(failing(&d).iter().any(|n| n.contains("UAV3") && n.contains("level")), "{:?}", failing(&d));
        // After reconnection the framework's value stays off the model's.
        let mut d = base.clone();
        for r in d.framework.rows.iter_mut().filter(|r| r[1] > 30.0) {
            r[col] += 5.0;
        }
        assert!(failing(&d).iter().any(|n| n.contains("UAV3") && n.contains("merges")), "{:?}", failing(&d));
        // A C reader missed a step, and one read a wrong value.
        let mut d = base.clone();
        d.c_readers[0].rows.remove(10);
        d.c_readers[1].rows[3][1] += 0.5;
        let f = failing(&d);
        assert!(f.iter().any(|n| n.starts_with("C component 1")) && f.iter().any(|n| n.starts_with("C component 2")));
        // A count that is off, away from every scripted change.
        let mut d = base.clone();
        d.connections.rows[20][3] = 5.0;
        assert_eq!(failing(&d), vec!["connection counts per domain follow the script".to_string()]);
        // A request sent late.
        let mut d = base.clone();
        d.events.rows[1][0] += 3.0;
        assert_eq!(
            failing(&d),
            vec!["the monitoring script sent every scripted disconnect / connect request on time".to_string()]
        );
        // The FMU component computed one answer wrong, or never answered.
        let mut d = base.clone();
        d.fmu.rows[40][3] += 0.01;
        assert_eq!(failing(&d), vec!["the FMU component filtered UAV1's elevation at every step".to_string()]);
        let mut d = base.clone();
        d.fmu.rows.iter_mut().for_each(|r| r[5] = 0.0);
        assert_eq!(failing(&d), vec!["the FMU component filtered UAV1's elevation at every step".to_string()]);
        // A UAV that never disconnected.
        let mut d = base;
        d.uavs[3].rows.iter_mut().for_each(|r| r[6] = 1.0);
        assert_eq!(failing(&d).iter().filter(|n| n.contains("UAV4")).count(), 2);
    }
}
