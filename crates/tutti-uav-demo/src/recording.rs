//! `framework.csv` and `altitude_filter.csv`, the framework's view of every step that the
//! checks and figures read, drawn from the run's CSV recording (`run-DOMAIN.csv`, one file
//! per domain: `step, sim_time, wall_s, connections`, then `publish.ITEM…` and
//! `subscribe.ITEM…`, docs/recording.md). The values are copied as recorded (full
//! precision), row by row: every domain is recorded at every step.

use std::path::Path;

use anyhow::{bail, Context};

use crate::scenario::UAVS;
use crate::sim::FMU_DOMAIN;

/// One domain's recording: its header and rows, as text.
struct Recorded {
    file: String,
    header: Vec<String>,
    rows: Vec<Vec<String>>,
}

impl Recorded {
    fn read(out: &Path, domain: &str) -> anyhow::Result<Recorded> {
        let file = format!("run-{domain}.csv");
        let text = std::fs::read_to_string(out.join(&file)).with_context(|| format!("reading {file}"))?;
        let mut lines = text.lines();
        let header: Vec<String> = lines.next().unwrap_or_default().split(',').map(str::to_string).collect();
        let rows = lines
            .map(|l| l.split(',').map(str::to_string).collect::<Vec<_>>())
            .filter(|r| r.len() == header.len())
            .collect();
        Ok(Recorded { file, header, rows })
    }

    fn col(&self, name: &str) -> anyhow::Result<usize> {
        self.header.iter().position(|h| h == name).with_context(|| format!("{}: no column {name}", self.file))
    }
}

/// Writes `framework.csv` and `altitude_filter.csv` in `out` from its `run-*.csv` files.
pub fn demo_tables(out: &Path) -> anyhow::Result<()> {
    let uavs: Vec<Recorded> =
        (1..=UAVS).map(|i| Recorded::read(out, &format!("multiuav_uav{i}"))).collect::<anyhow::Result<_>>()?;
    let fmu = Recorded::read(out, FMU_DOMAIN)?;
    let n = uavs.iter().chain(std::iter::once(&fmu)).map(|r| r.rows.len()).min().unwrap_or(0);
    // The same step on every row of every domain.
    let (step, sim, wall) = (uavs[0].col("step")?, uavs[0].col("sim_time")?, uavs[0].col("wall_s")?);
    for r in uavs.iter().chain(std::iter::once(&fmu)) {
        let (s, t) = (r.col("step")?, r.col("sim_time")?);
        if let Some(k) = (0..n).find(|&k| r.rows[k][s] != uavs[0].rows[k][step] || r.rows[k][t] != uavs[0].rows[k][sim])
        {
            bail!(
                "{} row {} is step {}, {} has step {}",
                r.file,
                k + 1,
                r.rows[k][s],
                uavs[0].file,
                uavs[0].rows[k][step]
            );
        }
    }
    let mut header = vec!["step".to_string(), "sim_time".into(), "wall_s".into()];
    let mut cols = Vec::new();
    for (i, r) in uavs.iter().enumerate() {
        for (c, from) in [
            ("elevation", "subscribe.Elevation"),
            ("time", "subscribe.Time"),
            ("altitude_pub", "publish.Altitude"),
            ("connections", "connections"),
        ] {
            header.push(format!("uav{}_{c}", i + 1));
            cols.push((i, r.col(from)?));
        }
    }
    let mut text = header.join(",") + "\n";
    for k in 0..n {
        let first = &uavs[0].rows[k];
        let mut row = vec![first[step].as_str(), first[sim].as_str(), first[wall].as_str()];
        row.extend(cols.iter().map(|&(i, c)| uavs[i].rows[k][c].as_str()));
        text.push_str(&row.join(","));
        text.push('\n');
    }
    std::fs::write(out.join("framework.csv"), text).context("writing framework.csv")?;

    let mut text = "step,sim_time,elevation,altitude,climb_rate,steps,connections\n".to_string();
    let cols =
        ["step", "sim_time", "publish.elevation", "subscribe.altitude", "subscribe.climb_rate", "subscribe.steps"]
            .iter()
            .chain(std::iter::once(&"connections"))
            .map(|c| fmu.col(c))
            .collect::<anyhow::Result<Vec<_>>>()?;
    for r in &fmu.rows[..n] {
        let row: Vec<&str> = cols.iter().map(|&c| r[c].as_str()).collect();
        text.push_str(&row.join(","));
        text.push('\n');
    }
    std::fs::write(out.join("altitude_filter.csv"), text).context("writing altitude_filter.csv")?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A recording of two steps: every domain's file, as `tutti run` writes it.
    fn recorded(dir: &Path) {
        for i in 1..=UAVS {
            let mut text = "step,sim_time,wall_s,connections,publish.Autopilot,publish.X,publish.Y,publish.Z,\
publish.Airspeed,publish.Altitude,publish.Time,subscribe.Latitude,subscribe.Longitude,subscribe.Elevation,\
subscribe.Airspeed,subscribe.Heading,subscribe.Time\n"
                .to_string();
            for k in 0..2 {
                let e = 300.0 + i as f64 + k as f64 * 0.123456789012345;
                let alt = if k == 0 { 0.0 } else { 300.0 + i as f64 };
                text.push_str(&format!(
                    "{},{:.6},{:.6},1,1,0,0,0,25,{alt},{},45.5,-73.6,{e},25,0,{}\n",
                    7 + k,
                    k as f64 * 0.05,
                    k as f64 * 0.0125,
                    k as f64 * 0.05,
                    k as f64 * 0.05
                ));
            }
            std::fs::write(dir.join(format!("run-multiuav_uav{i}.csv")), text).unwrap();
        }
        let fmu = "step,sim_time,wall_s,connections,publish.elevation,subscribe.altitude,subscribe.climb_rate,subscribe.steps\n\
7,0.000000,0.000000,1,0,0,0,0\n8,0.050000,0.012500,1,301,7.525,150.5,1\n9,0.100000,0.025000,1,301.5,15,150,2\n";
        std::fs::write(dir.join(format!("run-{FMU_DOMAIN}.csv")), fmu).unwrap();
    }

    #[test]
    fn the_demo_tables_are_the_recorded_values_step_by_step() {
        let dir = tempfile::tempdir().unwrap();
        recorded(dir.path());
        demo_tables(dir.path()).unwrap();
        let fw = std::fs::read_to_string(dir.path().join("framework.csv")).unwrap();
        let lines: Vec<&str> = fw.lines().collect();
        assert_eq!(lines.len(), 3, "a header and the two steps every domain has: {fw}");
        assert!(
            lines[0].starts_with("step,sim_time,wall_s,uav1_elevation,uav1_time,uav1_altitude_pub,uav1_connections,")
        );
        assert!(lines[0].ends_with("uav4_connections"));
        let e = format!("{}", 301.0 + 0.123456789012345);
        assert_eq!(lines[2].split(',').nth(3), Some(e.as_str()), "as recorded, full precision: {fw}");
        assert!(lines[2].starts_with(&format!("8,0.050000,0.012500,{e},0.05,301,1,")), "{fw}");
        let filter = std::fs::read_to_string(dir.path().join("altitude_filter.csv")).unwrap();
        assert_eq!(
            filter,
            "step,sim_time,elevation,altitude,climb_rate,steps,connections\n7,0.000000,0,0,0,0,1\n8,0.050000,301,7.525,150.5,1,1\n"
        );
        // A domain whose rows are not the same steps is refused.
        let p = dir.path().join(format!("run-{FMU_DOMAIN}.csv"));
        std::fs::write(&p, std::fs::read_to_string(&p).unwrap().replace("\n8,", "\n9,")).unwrap();
        assert!(demo_tables(dir.path()).unwrap_err().to_string().contains("row 2 is step 9"));
    }
}
