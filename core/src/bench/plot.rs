//! The bench's time-vs-error plot: one curve per method (its settings joined), ns/ray per core
//! on x, median depth error in texels on y (log scale). PNG via plotters with an embedded font.

use super::{method_name, BenchRow};
use crate::render::job::Method;

/// The curve a row belongs to: its method, with the paper-exact PDM and PDM over whole
/// prisms (no cells) as curves of their own.
fn series_name(r: &BenchRow) -> String {
    let name = if r.setting == "paper" {
        format!("{} (paper prism)", method_name(r.method))
    } else if r.setting.starts_with("whole,") {
        format!("{} (whole prisms)", method_name(r.method))
    } else {
        method_name(r.method)
    };
    match r.seams {
        crate::seam::SeamMode::Stitch => name,
        crate::seam::SeamMode::Open => format!("{name}, open seams"),
    }
}
use crate::error::{Error, Result};
use plotters::prelude::*;
use std::path::Path;

static FONT: &[u8] = include_bytes!("../../assets/DejaVuSans.ttf");

fn register_font() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT);
    });
}

/// Write the plot for one asset's rows as PNG (atomically).
pub fn write_plot(path: &Path, title: &str, rows: &[BenchRow]) -> Result<()> {
    register_font();
    // The reference is the zero of the error axis: give its time in the title instead.
    let reference_ns = rows
        .iter()
        .find(|r| r.method == Method::Reference)
        .map(|r| r.ns_per_ray);
    let title = match reference_ns {
        Some(ns) => format!("{title} (reference: {ns:.0} ns/ray)"),
        None => title.to_string(),
    };
    let rows: Vec<&BenchRow> = rows
        .iter()
        .filter(|r| r.method != Method::Reference)
        .collect();
    let pts: Vec<(f64, f64)> = rows
        .iter()
        .map(|r| (r.ns_per_ray, r.depth_err_median_texels.max(1e-6)))
        .filter(|(x, y)| x.is_finite() && y.is_finite())
        .collect();
    if pts.is_empty() {
        return Err(Error::Param("bench: nothing to plot".into()));
    }
    let (w, h) = (900u32, 600u32);
    let mut buf = vec![0u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        let draw = |e: &dyn std::fmt::Display| Error::Param(format!("bench plot: {e}"));
        root.fill(&WHITE).map_err(|e| draw(&e))?;
        let xmax = pts.iter().map(|p| p.0).fold(0.0, f64::max) * 1.15;
        let ymin = pts.iter().map(|p| p.1).fold(f64::INFINITY, f64::min) / 2.0;
        let ymax = pts.iter().map(|p| p.1).fold(0.0, f64::max) * 2.0;
        let mut chart = ChartBuilder::on(&root)
            .caption(&title, ("sans-serif", 22))
            .margin(16)
            .x_label_area_size(44)
            .y_label_area_size(70)
            .build_cartesian_2d(0.0..xmax, (ymin..ymax).log_scale())
            .map_err(|e| draw(&e))?;
        chart
            .configure_mesh()
            .x_desc("time per ray per core (ns)")
            .y_desc("median depth error (texels)")
            .y_label_formatter(&|v| format!("{v:.0e}"))
            .x_label_formatter(&|v| format!("{v:.0}"))
            .draw()
            .map_err(|e| draw(&e))?;
        let mut methods: Vec<String> = rows.iter().map(|r| series_name(r)).collect();
        methods.dedup();
        for (i, m) in methods.iter().enumerate() {
            let colour = Palette99::pick(i).to_rgba();
            let mut series: Vec<(f64, f64)> = rows
                .iter()
                .filter(|r| &series_name(r) == m)
                .map(|r| (r.ns_per_ray, r.depth_err_median_texels.max(1e-6)))
                .collect();
            series.sort_by(|a, b| a.0.total_cmp(&b.0));
            chart
                .draw_series(LineSeries::new(series.clone(), colour.stroke_width(2)))
                .map_err(|e| draw(&e))?
                .label(m.clone())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(3))
                });
            chart
                .draw_series(series.iter().map(|&p| Circle::new(p, 4, colour.filled())))
                .map_err(|e| draw(&e))?;
        }
        chart
            .configure_series_labels()
            .border_style(BLACK)
            .background_style(WHITE.mix(0.8))
            .draw()
            .map_err(|e| draw(&e))?;
        root.present().map_err(|e| draw(&e))?;
    }
    crate::render::output::write_png_rgb(path, w, h, &buf)
}
