//! Flies the default four-UAV formation and prints the published outputs as CSV, one row per
//! UAV every `period` seconds: `cargo run -p tutti-uav --example formation_trace -- [seconds] [period]`.
//! Plot `elevation_m` against `time` per UAV for the altitude-versus-time view of the paper's Figure 5.

use tutti_uav::{scenario, DEFAULT_DT};

fn main() {
    let mut args = std::env::args().skip(1);
    let seconds: f64 = args.next().and_then(|s| s.parse().ok()).unwrap_or(120.0);
    let period: f64 = args.next().and_then(|s| s.parse().ok()).unwrap_or(1.0);
    let mut uavs = match scenario::default_formation().build_all() {
        Ok(uavs) => uavs,
        Err(e) => {
            eprintln!("formation_trace: {e}");
            std::process::exit(1);
        }
    };
    let every = ((period / DEFAULT_DT).round() as usize).max(1);
    let steps = (seconds / DEFAULT_DT).round() as usize;
    println!("uav,time,lat_deg,lon_deg,elevation_m,airspeed,heading_deg");
    for k in 0..=steps {
        if k % every == 0 {
            for (i, uav) in uavs.iter().enumerate() {
                let o = uav.outputs();
                println!(
                    "{},{:.2},{:.7},{:.7},{:.2},{:.2},{:.1}",
                    i + 1,
                    o.time,
                    o.lat_deg,
                    o.lon_deg,
                    o.elevation_m,
                    o.airspeed,
                    o.heading_deg
                );
            }
        }
        for uav in &mut uavs {
            uav.step(DEFAULT_DT);
        }
    }
}
