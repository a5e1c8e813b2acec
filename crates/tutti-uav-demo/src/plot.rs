//! The two pictures of the demo, after Figures 5 and 6 of the paper, drawn with plotters as
//! SVG and rasterised to PNG in the font `tutti-plot` finds.

use std::path::Path;

use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::prelude::*;
use tutti_plot::{font, write_svg_and_png};

use crate::analysis::{observed_windows, RunData};
use crate::scenario::{Scenario, UAVS};

/// A darker shade of `c`, for the dots drawn over its solid line.
fn darker(c: RGBColor) -> RGBColor {
    RGBColor(c.0 / 2, c.1 / 2, c.2 / 2)
}

/// One colour per UAV (colour-blind-safe palette).
const UAV_COLORS: [RGBColor; UAVS] =
    [RGBColor(0, 114, 178), RGBColor(213, 94, 0), RGBColor(0, 158, 115), RGBColor(204, 121, 167)];

fn pairs(xs: &[f64], ys: &[f64]) -> Vec<(f64, f64)> {
    xs.iter().zip(ys).filter(|(x, y)| x.is_finite() && y.is_finite()).map(|(&x, &y)| (x, y)).collect()
}

fn y_range(series: &[&[(f64, f64)]]) -> (f64, f64) {
    let ys = series.iter().flat_map(|s| s.iter().map(|p| p.1));
    let (lo, hi) = ys.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), y| (a.min(y), b.max(y)));
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    let pad = ((hi - lo) * 0.08).max(1.0);
    (lo - pad, hi + pad)
}

/// A connect / disconnect as it happened: time, UAV, connected afterwards.
fn observed_events(d: &RunData) -> Vec<(f64, usize, bool)> {
    let mut out = Vec::new();
    for (i, t) in d.uavs.iter().enumerate() {
        for (a, b) in observed_windows(t) {
            out.push((a, i + 1, false));
            if b.is_finite() {
                out.push((b, i + 1, true));
            }
        }
    }
    out.sort_by(|a, b| a.0.total_cmp(&b.0));
    out
}

/// The legend box of every figure: white, framed, at `position`.
fn draw_legend<'a, DB: DrawingBackend + 'a, CT: CoordTranslate>(
    chart: &mut ChartContext<'a, DB, CT>,
    position: SeriesLabelPosition,
) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    chart
        .configure_series_labels()
        .position(position)
        .background_style(WHITE.mix(0.9))
        .border_style(BLACK)
        .label_font(("sans-serif", 17))
        .draw()?;
    Ok(())
}

/// The axes every plot of the demo shares: simulated time across (0 to `duration`), `y`
/// upwards with `y_desc`, whole-number labels, light grid; `x_area` is the height of the
/// time axis' label area, `y_labels` the number of labels upwards (plotters' default if None).
fn time_chart<'a, 'b, DB: DrawingBackend + 'a>(
    mut builder: ChartBuilder<'a, 'b, DB>,
    duration: f64,
    y: std::ops::Range<f64>,
    x_area: u32,
    y_desc: &str,
    y_labels: Option<usize>,
) -> anyhow::Result<ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>>
where
    DB::ErrorType: 'static,
{
    let mut chart = builder
        .margin(20)
        .margin_right(40)
        .x_label_area_size(x_area)
        .y_label_area_size(80)
        .build_cartesian_2d(0.0..duration, y)?;
    let mut mesh = chart.configure_mesh();
    mesh.x_desc("simulated time (s)")
        .y_desc(y_desc)
        .axis_desc_style(("sans-serif", 22))
        .label_style(("sans-serif", 18))
        .y_label_formatter(&|v| format!("{v:.0}"))
        .x_label_formatter(&|v| format!("{v:.0}"))
        .light_line_style(RGBColor(235, 235, 235));
    if let Some(n) = y_labels {
        mesh.y_labels(n);
    }
    mesh.draw()?;
    Ok(chart)
}

/// Figure 5: altitude of the four UAVs; dotted = computed by the models, solid = read by
/// the framework; the monitoring script's disconnect / connect events marked.
pub fn figure5(path: &Path, s: &Scenario, d: &RunData) -> anyhow::Result<()> {
    let font_file = font()?;
    let mut svg = String::new();
    draw_figure5(SVGBackend::with_string(&mut svg, (1400, 820)).into_drawing_area(), s, d)?;
    Ok(write_svg_and_png(&svg, path, &font_file)?)
}

fn draw_figure5<DB: DrawingBackend>(root: DrawingArea<DB, Shift>, s: &Scenario, d: &RunData) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE)?;
    // The legend in a strip of its own on the right, so that the plot needs no empty band.
    let (root, side) = root.split_horizontally(1130);
    let t = d.framework.col("sim_time");
    // Before a UAV's first answer the framework reads the DDF's default (0): not an altitude.
    let solid: Vec<Vec<(f64, f64)>> = (1..=UAVS)
        .map(|i| {
            let read = pairs(&t, &d.framework.col(&format!("uav{i}_elevation")));
            read.into_iter().skip_while(|p| p.1 == 0.0).collect()
        })
        .collect();
    let dotted: Vec<Vec<(f64, f64)>> = d.uavs.iter().map(|u| pairs(&u.col("time_s"), &u.col("altitude_m"))).collect();
    let all: Vec<&[(f64, f64)]> = solid.iter().chain(&dotted).map(|v| v.as_slice()).collect();
    let (lo, hi) = y_range(&all);
    // Room for the event labels above.
    let (lo, hi) = (lo - (hi - lo) * 0.04, hi + (hi - lo) * 0.14);
    let mut builder = ChartBuilder::on(&root);
    builder
        .caption("Figure 5. Altitude of the UAVs: computed by the models, read by the framework", ("sans-serif", 24));
    let mut chart = time_chart(builder, s.duration, lo..hi, 55, "altitude above mean sea level (m)", None)?;
    for (k, (t, uav, on)) in observed_events(d).into_iter().enumerate() {
        let color = if on { RGBColor(40, 140, 40) } else { RGBColor(200, 40, 40) };
        chart.draw_series(DashedLineSeries::new(vec![(t, lo), (t, hi)], 8, 6, color.stroke_width(1)))?;
        let label = format!("UAV{uav} {}", if on { "connects" } else { "disconnects" });
        let y = hi - (hi - lo) * (0.03 + 0.045 * (k % 2) as f64);
        chart.draw_series(std::iter::once(Text::new(
            label,
            (t + 0.4, y),
            ("sans-serif", 17).into_font().color(&color),
        )))?;
    }
    for i in 0..UAVS {
        let c = UAV_COLORS[i];
        let dark = darker(c);
        chart.draw_series(LineSeries::new(solid[i].iter().copied(), c.stroke_width(3)))?;
        chart.draw_series(DottedLineSeries::new(dotted[i].iter().copied(), 0, 7, move |p| {
            Circle::new(p, 2, dark.filled())
        }))?;
    }
    // The legend: one entry per UAV, then the two line styles explained once.
    let mut entries: Vec<(String, RGBColor, bool, bool)> =
        (0..UAVS).map(|i| (format!("UAV{}", i + 1), UAV_COLORS[i], true, true)).collect();
    entries.push(("read by the framework".into(), BLACK, true, false));
    entries.push(("computed by the model".into(), BLACK, false, true));
    side_legend(&side, &entries)?;
    root.present()?;
    Ok(())
}

/// A legend drawn in its own area: per entry a sample (a solid line, dots, or both) and its
/// label, from the top, framed.
fn side_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    entries: &[(String, RGBColor, bool, bool)],
) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    let (x0, y0, row) = (12i32, 70i32, 30i32);
    let height = row * entries.len() as i32 + 16;
    area.draw(&Rectangle::new([(x0 - 8, y0 - 20), (262, y0 - 20 + height)], BLACK.stroke_width(1)))?;
    for (k, (label, c, line, dots)) in entries.iter().enumerate() {
        let y = y0 + row * k as i32;
        if *line {
            area.draw(&PathElement::new(vec![(x0, y), (x0 + 36, y)], c.stroke_width(3)))?;
        }
        if *dots {
            let dark = if *line { darker(*c) } else { *c };
            for dx in [6, 18, 30] {
                area.draw(&Circle::new((x0 + dx, y), 2, dark.filled()))?;
            }
        }
        area.draw(&Text::new(label.clone(), (x0 + 46, y - 9), ("sans-serif", 17).into_font()))?;
    }
    Ok(())
}

/// Figure 6: UAV2's altitude as read by the framework and by the two C components, and the
/// number of connected participants of each domain over time.
pub fn figure6(path: &Path, s: &Scenario, d: &RunData) -> anyhow::Result<()> {
    let font_file = font()?;
    let mut svg = String::new();
    draw_figure6(SVGBackend::with_string(&mut svg, (1400, 1000)).into_drawing_area(), s, d)?;
    Ok(write_svg_and_png(&svg, path, &font_file)?)
}

fn draw_figure6<DB: DrawingBackend>(root: DrawingArea<DB, Shift>, s: &Scenario, d: &RunData) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    let uav = s.c_domain_uav;
    root.fill(&WHITE)?;
    let root =
        root.titled(&format!("Figure 6. Heterogeneous participants of domain multiuav_uav{uav}"), ("sans-serif", 26))?;
    let (top, bottom) = root.split_vertically(560);
    let t = d.framework.col("sim_time");
    let fw_read: Vec<(f64, f64)> =
        pairs(&t, &d.framework.col(&format!("uav{uav}_elevation"))).into_iter().skip_while(|p| p.1 == 0.0).collect();
    let model = d.uavs.get(uav - 1).map(|u| pairs(&u.col("time_s"), &u.col("altitude_m"))).unwrap_or_default();
    let readers: Vec<Vec<(f64, f64)>> = d.c_readers.iter().map(|r| pairs(&r.col("time"), &r.col("altitude"))).collect();
    let mut all: Vec<&[(f64, f64)]> = vec![&fw_read, &model];
    all.extend(readers.iter().map(|v| v.as_slice()));
    let (lo, hi) = y_range(&all);
    let mut chart =
        time_chart(ChartBuilder::on(&top), s.duration, lo..hi, 50, &format!("UAV{uav} altitude (m)"), None)?;
    for (j, &t) in s.c_readers.iter().enumerate() {
        let grey = RGBColor(90, 90, 90);
        chart.draw_series(DashedLineSeries::new(vec![(t, lo), (t, hi)], 8, 6, grey.stroke_width(1)))?;
        let y = lo + (hi - lo) * (0.06 + 0.07 * (j % 2) as f64);
        let label = format!("C component {} connects", j + 1);
        chart.draw_series(std::iter::once(Text::new(
            label,
            (t + 0.4, y),
            ("sans-serif", 17).into_font().color(&grey),
        )))?;
    }
    let reader_styles = [(RGBColor(230, 159, 0), 12u32), (RGBColor(0, 158, 115), 6u32)];
    for (j, r) in readers.iter().enumerate() {
        let (c, w) = reader_styles[j % reader_styles.len()];
        let start = s.c_readers.get(j).copied().unwrap_or(0.0);
        chart
            .draw_series(LineSeries::new(r.iter().copied(), c.mix(0.55).stroke_width(w)))?
            .label(format!("read by C component {} (connects at {start:.0} s)", j + 1))
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 30, y)], c.mix(0.55).stroke_width(w)));
    }
    let c = UAV_COLORS[uav - 1];
    chart
        .draw_series(LineSeries::new(fw_read.iter().copied(), c.stroke_width(2)))?
        .label("read by the framework")
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 30, y)], c.stroke_width(2)));
    chart
        .draw_series(DottedLineSeries::new(model.iter().copied(), 0, 7, |p| Circle::new(p, 2, BLACK.filled())))?
        .label("computed by the UAV model")
        .legend(|(x, y)| {
            EmptyElement::at((x, y)) + Circle::new((6, 0), 2, BLACK.filled()) + Circle::new((18, 0), 2, BLACK.filled())
        });
    draw_legend(&mut chart, SeriesLabelPosition::UpperLeft)?;

    // Connected participants per domain, as the monitoring script saw them.
    let ct = d.connections.col("sim_time");
    let counts: Vec<Vec<(f64, f64)>> = (1..=UAVS).map(|i| pairs(&ct, &d.connections.col(&format!("uav{i}")))).collect();
    let max = counts.iter().flatten().map(|p| p.1).fold(0.0, f64::max).max(1.0);
    let y_labels = Some((max as usize) + 2);
    let mut chart =
        time_chart(ChartBuilder::on(&bottom), s.duration, -0.2..max + 0.8, 55, "connected participants", y_labels)?;
    for (i, pts) in counts.iter().enumerate() {
        let c = UAV_COLORS[i];
        // Step lines at the exact counts; drawn widest first, so that where domains have the
        // same count every one still shows, as nested bands.
        let mut stairs = Vec::with_capacity(pts.len() * 2);
        for w in pts.windows(2) {
            stairs.push((w[0].0, w[0].1));
            stairs.push((w[1].0, w[0].1));
        }
        let width = 11 - 3 * i as u32;
        chart
            .draw_series(LineSeries::new(stairs, c.stroke_width(width)))?
            .label(format!("multiuav_uav{}", i + 1))
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 30, y)], c.stroke_width(width)));
    }
    draw_legend(&mut chart, SeriesLabelPosition::UpperLeft)?;
    root.present()?;
    Ok(())
}
