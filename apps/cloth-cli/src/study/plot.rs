//! The study's picture: one panel per scene, stacked, each RMS error against cost, log–log, one
//! curve per backend and integrator (colour: integrator; marker: backend, in the order given:
//! filled circle, open circle, triangle, cross; f64 lighter), each backend's Pareto front
//! circled. Drawn once for SVG and once for PNG.

use std::path::Path;

use anyhow::{Context, Result, anyhow};
use cloth_core::Integrator;
use plotters::coord::Shift;
use plotters::prelude::*;

use super::{Row, Study};

/// Size of one scene's panel in pixels.
const PANEL: (u32, u32) = (1000, 650);

/// Indices of the rows on `backend`'s Pareto front: no other finite row of that backend is both
/// cheaper and more accurate.
pub fn pareto_front(rows: &[Row], backend: &str) -> Vec<usize> {
    let ok = |r: &Row| r.backend == backend && r.plottable();
    (0..rows.len())
        .filter(|&i| {
            ok(&rows[i])
                && !rows.iter().any(|o| {
                    ok(o)
                        && o.cost_ms() <= rows[i].cost_ms()
                        && o.rms_error_m <= rows[i].rms_error_m
                        && (o.cost_ms() < rows[i].cost_ms() || o.rms_error_m < rows[i].rms_error_m)
                })
        })
        .collect()
}

/// A run's colour: its integrator's, lighter for the f64 backend.
fn series_color(backend: &str, integrator: Integrator) -> RGBAColor {
    let base = integrator_color(integrator);
    if backend == "cpu-f64" { base.mix(0.45) } else { base.to_rgba() }
}

/// Draws one backend's markers (the `b`-th backend: filled circle, open circle, triangle, cross).
fn draw_markers<DB: DrawingBackend, CT: CoordTranslate<From = (f64, f64)>>(
    chart: &mut ChartContext<'_, DB, CT>,
    b: usize,
    color: RGBAColor,
    at: &[(f64, f64)],
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let at = at.iter().copied();
    match b % 4 {
        0 => chart.draw_series(at.map(|p| Circle::new(p, 4, color.filled()))).map(|_| ()),
        1 => chart.draw_series(at.map(|p| Circle::new(p, 4, color.stroke_width(2)))).map(|_| ()),
        2 => chart.draw_series(at.map(|p| TriangleMarker::new(p, 6, color.filled()))).map(|_| ()),
        _ => chart.draw_series(at.map(|p| Cross::new(p, 5, color.stroke_width(2)))).map(|_| ()),
    }
}

/// The `b`-th backend's marker at a legend position.
fn legend_marker<DB: DrawingBackend>(
    b: usize,
    color: RGBAColor,
    at: (i32, i32),
) -> DynElement<'static, DB, (i32, i32)> {
    match b % 4 {
        0 => Circle::new(at, 4, color.filled()).into_dyn(),
        1 => Circle::new(at, 4, color.stroke_width(2)).into_dyn(),
        2 => TriangleMarker::new(at, 6, color.filled()).into_dyn(),
        _ => Cross::new(at, 5, color.stroke_width(2)).into_dyn(),
    }
}

fn integrator_color(integrator: Integrator) -> RGBColor {
    match integrator {
        Integrator::SemiImplicitEuler => RGBColor(215, 40, 40),
        Integrator::VelocityVerlet => RGBColor(40, 70, 215),
        Integrator::RungeKutta4 => RGBColor(0, 145, 0),
        Integrator::Xpbd => RGBColor(240, 135, 0),
        Integrator::BackwardEuler => RGBColor(130, 40, 170),
        Integrator::Vbd => RGBColor(0, 150, 160),
    }
}

/// The plot's text uses a font compiled in (egui's default sans-serif, Ubuntu Light), so the PNG
/// needs no system fonts.
pub(crate) fn register_font() -> Result<()> {
    static REGISTERED: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        plotters::style::register_font("sans-serif", FontStyle::Normal, epaint_default_fonts::UBUNTU_LIGHT).is_ok()
    });
    if ok { Ok(()) } else { Err(anyhow!("the plot font (Ubuntu Light) could not be loaded")) }
}

/// Writes the plot, a panel per scene, as SVG and PNG.
pub fn write(studies: &[Study], svg: &Path, png: &Path) -> Result<()> {
    register_font()?;
    let size = (PANEL.0, PANEL.1 * studies.len().max(1) as u32);
    let mut text = String::new();
    draw_all(SVGBackend::with_string(&mut text, size).into_drawing_area(), studies)
        .with_context(|| format!("cannot draw {}", svg.display()))?;
    cloth_backends::output::write_atomically(svg, text.as_bytes())?;
    let mut pixels = vec![0u8; (size.0 * size.1 * 3) as usize];
    draw_all(BitMapBackend::with_buffer(&mut pixels, size).into_drawing_area(), studies)
        .with_context(|| format!("cannot draw {}", png.display()))?;
    Ok(cloth_backends::output::write_atomically(
        png,
        &crate::picture::encode_png(&pixels, size.0, size.1, png::ColorType::Rgb)?,
    )?)
}

fn draw_all<DB: DrawingBackend>(root: DrawingArea<DB, Shift>, studies: &[Study]) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow!("{e}");
    root.fill(&WHITE).map_err(err)?;
    for (panel, study) in root.split_evenly((studies.len().max(1), 1)).into_iter().zip(studies) {
        draw(panel, study)?;
    }
    root.present().map_err(err)?;
    Ok(())
}

fn draw<DB: DrawingBackend>(root: DrawingArea<DB, Shift>, study: &Study) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow!("{e}");
    let rows = &study.rows;
    let points: Vec<&Row> = rows.iter().filter(|r| r.plottable()).collect();
    let caption = format!(
        "Error against cost: {} ({}×{}), {:.2} s simulated, vs an f64 RK4 reference",
        study.scene.name,
        study.scene.cloth.resolution[0],
        study.scene.cloth.resolution[1],
        study.frames as f64 * study.scene.time.frame_dt
    );
    if points.is_empty() {
        root.titled(&caption, ("sans-serif", 20)).map_err(err)?;
        return Ok(());
    }
    let (x0, x1) = points.iter().fold((f64::MAX, f64::MIN), |(a, b), r| (a.min(r.cost_ms()), b.max(r.cost_ms())));
    let (y0, y1) = points.iter().fold((f64::MAX, f64::MIN), |(a, b), r| (a.min(r.rms_error_m), b.max(r.rms_error_m)));
    let mut chart = ChartBuilder::on(&root)
        .caption(caption, ("sans-serif", 20))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d((x0 * 0.7..x1 * 1.4).log_scale(), (y0 * 0.4..y1 * 2.5).log_scale())
        .map_err(err)?;
    chart
        .configure_mesh()
        .bold_line_style(RGBColor(200, 200, 200))
        .light_line_style(RGBColor(240, 240, 240))
        .x_desc("ms per simulated second (GPU timestamps on the GPU backends, wall clock on the CPU)")
        .y_desc("RMS position error (m)")
        .x_label_formatter(&|v| {
            let digits = if *v >= 10.0 {
                0
            } else if *v >= 1.0 {
                1
            } else {
                3
            };
            format!("{v:.digits$}")
        })
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(err)?;
    let mut backends: Vec<&str> = Vec::new();
    for r in &points {
        if !backends.contains(&r.backend.as_str()) {
            backends.push(&r.backend);
        }
    }
    for (b, backend) in backends.iter().enumerate() {
        for integrator in Integrator::ALL {
            let series: Vec<(f64, f64)> = points
                .iter()
                .filter(|r| r.backend == *backend && r.integrator == integrator)
                .map(|r| (r.cost_ms(), r.rms_error_m))
                .collect();
            if series.is_empty() {
                continue;
            }
            let color = series_color(backend, integrator);
            chart.draw_series(LineSeries::new(series.iter().copied(), color.stroke_width(2))).map_err(err)?;
            draw_markers(&mut chart, b, color, &series).map_err(err)?;
        }
    }
    // The legend: one entry per integrator (colour), one per backend (marker).
    for integrator in Integrator::ALL {
        if points.iter().any(|r| r.integrator == integrator) {
            let style = integrator_color(integrator).stroke_width(3);
            chart
                .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())
                .map_err(err)?
                .label(integrator.name())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], style));
        }
    }
    for (b, backend) in backends.iter().enumerate() {
        let color = if *backend == "cpu-f64" { BLACK.mix(0.45) } else { BLACK.to_rgba() };
        chart
            .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())
            .map_err(err)?
            .label(format!("{backend}{}", if *backend == "cpu-f64" { " (lighter)" } else { "" }))
            .legend(move |(x, y)| legend_marker(b, color, (x + 10, y)));
    }
    let front: Vec<(f64, f64)> =
        backends.iter().flat_map(|b| pareto_front(rows, b)).map(|i| (rows[i].cost_ms(), rows[i].rms_error_m)).collect();
    chart
        .draw_series(front.iter().map(|&p| Circle::new(p, 9, BLACK.stroke_width(2))))
        .map_err(err)?
        .label("Pareto front (per backend)")
        .legend(|(x, y)| Circle::new((x + 10, y), 6, BLACK.stroke_width(2)));
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 13))
        // Lower left: cheap and accurate at once, the corner no run reaches.
        .position(SeriesLabelPosition::LowerLeft)
        .draw()
        .map_err(err)?;
    Ok(())
}
