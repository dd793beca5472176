//! PNG plots of a benchmark run, per scene × path, one line per mode: frame time per frame
//! (as Chang et al. 2008, Figure 14), triangles per frame, pixel error per frame (Figure 15:
//! grey-level share above, colour share below) and culled fraction per frame.
//!
//! Text (titles, axes, legends) needs a TrueType font, loaded once at run time from
//! `CITYWALK_PLOT_FONT` or the usual DejaVu Sans paths (`fonts-dejavu-core` on Debian). Without
//! one the plots are still written, without text, and a warning is logged: a missing font
//! never fails a benchmark.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use plotters::prelude::*;

use crate::run::{BenchError, FrameRecord};

/// Width and height of every plot in pixels.
pub const PLOT_SIZE: (u32, u32) = (960, 540);

/// Where a font is looked for, after `CITYWALK_PLOT_FONT`.
const FONT_PATHS: [&str; 4] = [
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
];

/// Line colours by mode index (colour-blind-friendly Okabe-Ito order, then greys).
const COLOURS: [RGBColor; 8] = [
    RGBColor(0, 0, 0),
    RGBColor(230, 159, 0),
    RGBColor(86, 180, 233),
    RGBColor(0, 158, 115),
    RGBColor(213, 94, 0),
    RGBColor(0, 114, 178),
    RGBColor(204, 121, 167),
    RGBColor(120, 120, 120),
];

/// Registers a system font with plotters once; returns whether text can be drawn.
pub fn font_available() -> bool {
    static LOADED: OnceLock<bool> = OnceLock::new();
    *LOADED.get_or_init(|| {
        let candidates = std::env::var_os("CITYWALK_PLOT_FONT")
            .map(PathBuf::from)
            .into_iter()
            .chain(FONT_PATHS.iter().map(PathBuf::from));
        for path in candidates {
            let Ok(bytes) = std::fs::read(&path) else {
                continue;
            };
            // plotters keeps fonts for the life of the process; this happens once.
            let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
            if plotters::style::register_font("sans-serif", FontStyle::Normal, bytes).is_ok() {
                tracing::debug!("plot font: {}", path.display());
                return true;
            }
        }
        tracing::warn!(
            "no TrueType font found (set CITYWALK_PLOT_FONT or install fonts-dejavu-core): \
             plots are written without text"
        );
        false
    })
}

/// One line of a chart: its name and its points.
type Series = (String, Vec<(f64, f64)>);

/// Writes the four plots of every scene × path in `records` into `dir`, with text when a font
/// is available; returns the files written.
pub fn write_plots(dir: &Path, records: &[FrameRecord]) -> Result<Vec<PathBuf>, BenchError> {
    write_plots_with_text(dir, records, font_available())
}

/// [`write_plots`] with text switched on or off (`with_text` needs [`font_available`]).
pub fn write_plots_with_text(
    dir: &Path,
    records: &[FrameRecord],
    with_text: bool,
) -> Result<Vec<PathBuf>, BenchError> {
    let mut keys: Vec<(&str, &str)> = Vec::new();
    for r in records {
        let key = (r.scene.as_str(), r.path.as_str());
        if !keys.contains(&key) {
            keys.push(key);
        }
    }
    let mut written = Vec::new();
    for (scene, path) in keys {
        let rows: Vec<&FrameRecord> = records
            .iter()
            .filter(|r| r.scene == scene && r.path == path)
            .collect();
        let series = |value: &dyn Fn(&FrameRecord) -> f64| -> Vec<Series> {
            let mut modes: Vec<&str> = Vec::new();
            for r in &rows {
                if !modes.contains(&r.mode.as_str()) {
                    modes.push(&r.mode);
                }
            }
            modes
                .into_iter()
                .map(|mode| {
                    let points = rows
                        .iter()
                        .filter(|r| r.mode == mode)
                        .map(|r| (r.frame as f64, value(r)))
                        .collect();
                    (mode.to_string(), points)
                })
                .collect()
        };
        let title = format!("{scene} / {path}");
        let charts: [(&str, Vec<Chart>); 4] = [
            (
                "frame-ms",
                vec![Chart {
                    title: format!("{title}: frame time"),
                    y_desc: "frame time (ms)",
                    series: series(&|r| r.frame_ms),
                }],
            ),
            (
                "triangles",
                vec![Chart {
                    title: format!("{title}: triangles drawn"),
                    y_desc: "triangles",
                    series: series(&|r| r.triangles as f64),
                }],
            ),
            (
                "pixel-error",
                vec![
                    Chart {
                        title: format!("{title}: pixel error, grey level differs"),
                        y_desc: "share of pixels (%)",
                        series: series(&|r| 100.0 * r.pixel_error_grey),
                    },
                    Chart {
                        title: format!("{title}: pixel error, a channel differs by > 40"),
                        y_desc: "share of pixels (%)",
                        series: series(&|r| 100.0 * r.pixel_error_colour),
                    },
                ],
            ),
            (
                "culled",
                vec![Chart {
                    title: format!("{title}: buildings culled"),
                    y_desc: "culled (%)",
                    series: series(&|r| 100.0 * r.culled_fraction),
                }],
            ),
        ];
        for (kind, panels) in charts {
            let file = dir.join(format!(
                "plot-{}-{}-{kind}.png",
                file_part(scene),
                file_part(path)
            ));
            write_png(&file, &panels, with_text).map_err(|reason| BenchError::Write {
                path: file.clone(),
                reason,
            })?;
            written.push(file);
        }
    }
    Ok(written)
}

/// A name made safe for a file name.
fn file_part(s: &str) -> String {
    s.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// One panel of a plot.
struct Chart {
    title: String,
    y_desc: &'static str,
    series: Vec<Series>,
}

/// Draws `panels` stacked vertically into an RGB buffer and encodes it as PNG.
fn write_png(file: &Path, panels: &[Chart], with_text: bool) -> Result<(), String> {
    let (w, h) = PLOT_SIZE;
    let mut buffer = vec![0u8; w as usize * h as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut buffer, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let areas = root.split_evenly((panels.len().max(1), 1));
        for (area, chart) in areas.iter().zip(panels) {
            draw_chart(area, chart, with_text)?;
        }
        root.present().map_err(|e| e.to_string())?;
    }
    let image = image::RgbImage::from_raw(w, h, buffer).ok_or("plot buffer size")?;
    image.save(file).map_err(|e| e.to_string())
}

fn draw_chart<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    chart: &Chart,
    with_text: bool,
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    let x_max = chart
        .series
        .iter()
        .flat_map(|(_, p)| p.iter().map(|&(x, _)| x))
        .fold(1.0_f64, f64::max);
    let y_max = chart
        .series
        .iter()
        .flat_map(|(_, p)| p.iter().map(|&(_, y)| y))
        .filter(|y| y.is_finite())
        .fold(0.0_f64, f64::max);
    let y_max = if y_max > 0.0 { y_max * 1.08 } else { 1.0 };
    let mut builder = ChartBuilder::on(area);
    builder.margin(12);
    if with_text {
        builder
            .caption(&chart.title, ("sans-serif", 18))
            .x_label_area_size(36)
            .y_label_area_size(64);
    }
    let mut ctx = builder
        .build_cartesian_2d(0.0..x_max, 0.0..y_max)
        .map_err(|e| e.to_string())?;
    if with_text {
        ctx.configure_mesh()
            .x_desc("frame")
            .y_desc(chart.y_desc)
            .label_style(("sans-serif", 13))
            .draw()
            .map_err(|e| e.to_string())?;
    } else {
        // No font: a frame around the plot area instead of labelled axes.
        ctx.plotting_area()
            .draw(&Rectangle::new(
                [(0.0, 0.0), (x_max, y_max)],
                BLACK.stroke_width(1),
            ))
            .map_err(|e| e.to_string())?;
    }
    for (i, (name, points)) in chart.series.iter().enumerate() {
        let colour = COLOURS[i % COLOURS.len()];
        let drawn = ctx
            .draw_series(LineSeries::new(
                points.iter().copied().filter(|(_, y)| y.is_finite()),
                colour.stroke_width(2),
            ))
            .map_err(|e| e.to_string())?;
        if with_text {
            drawn.label(name.as_str()).legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2))
            });
        }
    }
    if with_text && !chart.series.is_empty() {
        ctx.configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font(("sans-serif", 13))
            .draw()
            .map_err(|e| e.to_string())?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn records() -> Vec<FrameRecord> {
        let mut out = Vec::new();
        for (m, mode) in ["brute", "frustum", "quadtree"].into_iter().enumerate() {
            for frame in 0..12 {
                let f = frame as f64;
                out.push(FrameRecord {
                    scene: "tiny".into(),
                    path: "street".into(),
                    mode: mode.into(),
                    frame,
                    visible: 5,
                    drawn: 20 - 4 * m,
                    clusters: 0,
                    false_culls: 0,
                    culled_fraction: 0.2 * m as f64 + 0.01 * f,
                    triangles: 1000 - 200 * m as u64 + frame as u64,
                    triangle_share: 1.0 - 0.2 * m as f64,
                    distance_diameters: 0.1,
                    draw_calls: 21,
                    select_ms: 0.1,
                    frame_ms: 5.0 + m as f64 + (f * 0.7).sin(),
                    cpu_ms: 0.5 + 0.1 * m as f64,
                    pixel_error_grey: 0.001 * m as f64 * f,
                    pixel_error_colour: 0.0005 * m as f64 * f,
                    bound_px: 2.0,
                    differing_px: 0,
                    beyond_bound_px: 0,
                    gpu: citywalk_runtime::gpu_timer::GpuTimes::default(),
                });
            }
        }
        out
    }

    fn check_png(path: &Path) {
        let image = image::open(path).expect("plot decodes as PNG").to_rgb8();
        assert_eq!(image.dimensions(), PLOT_SIZE, "{}", path.display());
        let first = *image.get_pixel(0, 0);
        let distinct_colours = image.pixels().filter(|p| **p != first).count();
        assert!(distinct_colours > 1000, "{} is one colour", path.display());
    }

    #[test]
    fn plots_are_written_with_and_without_text() {
        for with_text in [false, font_available()] {
            let dir = std::env::temp_dir()
                .join(format!("citywalk-plots-{}-{with_text}", std::process::id()));
            std::fs::create_dir_all(&dir).unwrap();
            let files = write_plots_with_text(&dir, &records(), with_text).unwrap();
            assert_eq!(files.len(), 4);
            for f in &files {
                check_png(f);
            }
            assert!(dir.join("plot-tiny-street-pixel-error.png").exists());
            std::fs::remove_dir_all(&dir).unwrap();
        }
    }

    #[test]
    fn lines_differ_between_modes() {
        // The frame-time plot with a single mode differs from the one with three modes.
        let dir = std::env::temp_dir().join(format!("citywalk-plots-lines-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let all = records();
        let one: Vec<FrameRecord> = all.iter().filter(|r| r.mode == "brute").cloned().collect();
        write_plots_with_text(&dir, &all, false).unwrap();
        let three = image::open(dir.join("plot-tiny-street-frame-ms.png")).unwrap();
        write_plots_with_text(&dir, &one, false).unwrap();
        let single = image::open(dir.join("plot-tiny-street-frame-ms.png")).unwrap();
        assert_ne!(three.as_bytes(), single.as_bytes());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
