//! `tutti-bench scale --plot FILE.png`: the step's p50 against the participants, on log
//! scales, one colour per shape, tutti solid and HELICS dashed (FILE.svg beside it).

use std::path::Path;

use plotters::prelude::*;
use tutti_plot::{font, write_svg_and_png};

/// One line of the plot: a system's step p50 (µs) against N for one shape.
#[derive(Debug)]
pub struct Series {
    pub system: &'static str,
    pub shape: &'static str,
    /// Solid, or dashed (a peer's).
    pub dashed: bool,
    pub points: Vec<(f64, f64)>,
}

/// One colour per shape, in the order the shapes first appear (colour-blind-safe palette).
const COLORS: [RGBColor; 5] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(86, 180, 233),
];

/// Draws `series` on log scales.
pub fn plot(path: &Path, series: &[Series], cpus: usize) -> anyhow::Result<()> {
    let font_file = font()?;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (1100, 700)).into_drawing_area();
        root.fill(&WHITE)?;
        let all = || series.iter().flat_map(|s| s.points.iter().copied());
        let n_max = all().map(|p| p.0).fold(4.0, f64::max);
        let p_min = all().map(|p| p.1).fold(f64::INFINITY, f64::min).max(0.1);
        let p_max = all().map(|p| p.1).fold(1.0, f64::max);
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
        let mut shapes: Vec<&str> = Vec::new();
        for s in series.iter().filter(|s| !s.points.is_empty()) {
            let i = shapes.iter().position(|&n| n == s.shape).unwrap_or_else(|| {
                shapes.push(s.shape);
                shapes.len() - 1
            });
            let c = COLORS[i % COLORS.len()];
            let style = c.stroke_width(3);
            let drawn = if s.dashed {
                chart.draw_series(DashedLineSeries::new(s.points.clone(), 10, 6, style))?
            } else {
                chart.draw_series(LineSeries::new(s.points.clone(), style))?
            };
            let dashed = if s.dashed { " (dashed)" } else { "" };
            drawn
                .label(format!("{} {}{dashed}", s.system, s.shape))
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], c.stroke_width(3)));
            chart.draw_series(s.points.iter().map(|&p| Circle::new(p, 4, c.filled())))?;
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
