//! `tutti-bench scale --plot FILE.png`: the step's p50 against the participants, on log
//! scales, one colour per shape, tutti solid and HELICS dashed (FILE.svg beside it).

use std::path::Path;

use plotters::prelude::*;
use tutti_plot::{font, write_svg_and_png};

use crate::scale::{Figures, Shape};

/// One colour per shape (colour-blind-safe palette).
fn color(shape: Shape) -> RGBColor {
    match shape {
        Shape::Barrier => RGBColor(0, 114, 178),
        Shape::Hub => RGBColor(213, 94, 0),
        Shape::Leaves => RGBColor(0, 158, 115),
        Shape::Ring => RGBColor(204, 121, 167),
        Shape::FanOut => RGBColor(86, 180, 233),
    }
}

/// Draws the runs' p50 step times against N.
pub fn plot(path: &Path, runs: &[Figures], cpus: usize) -> anyhow::Result<()> {
    let font_file = font()?;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (1100, 700)).into_drawing_area();
        root.fill(&WHITE)?;
        let n_max = runs.iter().map(|r| r.n).max().unwrap_or(2).max(4) as f64;
        let p_min = runs.iter().map(|r| r.p50_us).fold(f64::INFINITY, f64::min).max(0.1);
        let p_max = runs.iter().map(|r| r.p50_us).fold(1.0, f64::max);
        let mut chart = ChartBuilder::on(&root)
            .caption(format!("Step time (p50) against participants, {cpus} CPUs"), ("sans-serif", 24))
            .margin(20)
            .x_label_area_size(50)
            .y_label_area_size(80)
            .build_cartesian_2d((1.5f64..n_max * 1.3).log_scale(), (p_min / 1.5..p_max * 1.5).log_scale())?;
        chart
            .configure_mesh()
            .x_desc("participants (N)")
            .y_desc("step p50 (µs)")
            .x_label_formatter(&|x| format!("{x:.0}"))
            .y_label_formatter(&|y| format!("{y:.0}"))
            .label_style(("sans-serif", 16))
            .draw()?;
        for shape in [Shape::Barrier, Shape::Hub, Shape::Leaves, Shape::Ring] {
            for system in ["tutti", "tutti (processes)", "HELICS"] {
                let points: Vec<(f64, f64)> = runs
                    .iter()
                    .filter(|r| r.shape == shape && r.system == system)
                    .map(|r| (r.n as f64, r.p50_us))
                    .collect();
                if points.is_empty() {
                    continue;
                }
                let c = color(shape);
                let dashed = if system == "HELICS" { " (dashed)" } else { "" };
                let label = format!("{system} {}{dashed}", shape.name());
                let style = c.stroke_width(3);
                let series = if system == "HELICS" {
                    chart.draw_series(DashedLineSeries::new(points.clone(), 10, 6, style))?
                } else {
                    chart.draw_series(LineSeries::new(points.clone(), style))?
                };
                series
                    .label(label)
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], c.stroke_width(3)));
                chart.draw_series(points.iter().map(|&p| Circle::new(p, 4, c.filled())))?;
            }
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .label_font(("sans-serif", 15))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()?;
        root.present()?;
    }
    Ok(write_svg_and_png(&svg, path, &font_file)?)
}
