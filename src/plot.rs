//! Pictures of a cone-SLAM run: the estimated map over the true cones and the
//! estimated trajectory over the true one. SVG or PNG by the file's extension.

use cairn_slam::{Color as ConeColor, Cone};
use nalgebra::Vector2;
use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use std::path::Path;
use std::sync::OnceLock;

/// What to draw; empty parts are left out.
#[derive(Default)]
pub struct MapPlot<'a> {
    /// Title above the plot.
    pub title: String,
    /// True cones (hollow circles).
    pub truth: &'a [Cone],
    /// Estimated cones (filled dots).
    pub map: &'a [Cone],
    /// True trajectory (grey line).
    pub true_path: &'a [Vector2<f64>],
    /// Estimated trajectory (red line).
    pub path: &'a [Vector2<f64>],
    /// The estimated trajectory's position error over time, (s, m): drawn
    /// in a panel below the map when given.
    pub errors: &'a [(f64, f64)],
}

/// How much the map's error arrows (mapped cone → its true cone) are
/// lengthened: centimetres would not show at a track's scale.
const ARROW_SCALE: f64 = 20.0;

fn rgb(color: ConeColor) -> RGBColor {
    match color {
        ConeColor::Blue => RGBColor(30, 80, 220),
        ConeColor::Yellow => RGBColor(230, 180, 0),
        ConeColor::Orange => RGBColor(255, 120, 0),
        ConeColor::BigOrange => RGBColor(200, 60, 0),
        ConeColor::Unknown => RGBColor(120, 120, 120),
    }
}

/// The plots' text font: Ubuntu Light, compiled in, so that drawing needs no
/// font from the system (nor fontconfig or freetype to find and render one).
pub(crate) const FONT: &str = "sans-serif";

/// Registers [`FONT`] with plotters, once.
fn register_font() -> Result<(), String> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = REGISTERED.get_or_init(|| {
        let bytes = epaint_default_fonts::UBUNTU_LIGHT;
        plotters::style::register_font(FONT, FontStyle::Normal, bytes).is_ok()
    });
    if *ok {
        Ok(())
    } else {
        Err("the plots' compiled-in font does not load".into())
    }
}

/// A picture that draws itself on any plotters backend.
pub(crate) trait Drawing {
    /// Its size in pixels.
    const SIZE: (u32, u32);
    /// Draws it on `area`.
    fn draw_on<DB: DrawingBackend>(
        &self,
        area: DrawingArea<DB, Shift>,
    ) -> Result<(), Box<dyn std::error::Error>>
    where
        DB::ErrorType: 'static;
}

/// Writes `drawing` to `path`: `.png` for a bitmap, otherwise SVG.
pub(crate) fn render<D: Drawing>(drawing: &D, path: &Path) -> Result<(), String> {
    register_font()?;
    let is_png = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("png"));
    let result = if is_png {
        drawing.draw_on(BitMapBackend::new(path, D::SIZE).into_drawing_area())
    } else {
        drawing.draw_on(SVGBackend::new(path, D::SIZE).into_drawing_area())
    };
    result.map_err(|e| format!("{}: {e}", path.display()))
}

/// Draws the chart's legend at `position` and finishes the picture.
pub(crate) fn finish<'a, DB: DrawingBackend + 'a>(
    chart: &mut ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>,
    position: SeriesLabelPosition,
) -> Result<(), Box<dyn std::error::Error>>
where
    DB::ErrorType: 'static,
{
    chart
        .configure_series_labels()
        .position(position)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    chart.plotting_area().present()?;
    Ok(())
}

/// Writes the plot to `path` (`.png` for a bitmap, otherwise SVG).
pub fn draw(plot: &MapPlot, path: &Path) -> Result<(), String> {
    render(plot, path)
}

impl Drawing for MapPlot<'_> {
    const SIZE: (u32, u32) = (1000, 800);

    fn draw_on<DB: DrawingBackend>(
        &self,
        area: DrawingArea<DB, Shift>,
    ) -> Result<(), Box<dyn std::error::Error>>
    where
        DB::ErrorType: 'static,
    {
        draw_map(self, area)
    }
}

fn draw_map<DB: DrawingBackend>(
    plot: &MapPlot,
    area: DrawingArea<DB, Shift>,
) -> Result<(), Box<dyn std::error::Error>>
where
    DB::ErrorType: 'static,
{
    area.fill(&WHITE)?;
    let area = if plot.errors.is_empty() {
        area
    } else {
        let (top, bottom) = area.split_vertically(area.dim_in_pixel().1 * 3 / 4);
        draw_errors(plot.errors, &bottom)?;
        top
    };
    let points = plot
        .truth
        .iter()
        .chain(plot.map)
        .map(|c| c.position)
        .chain(plot.true_path.iter().copied())
        .chain(plot.path.iter().copied());
    let (mut lo, mut hi) = (
        Vector2::repeat(f64::INFINITY),
        Vector2::repeat(f64::NEG_INFINITY),
    );
    for p in points {
        lo = lo.inf(&p);
        hi = hi.sup(&p);
    }
    if !lo.x.is_finite() {
        lo = Vector2::zeros();
        hi = Vector2::repeat(1.0);
    }
    // A band above the drawing for the legend, so it covers no cone.
    hi.y += 0.15 * (hi.y - lo.y).max(hi.x - lo.x);
    // Equal scales on both axes: widen the narrower range.
    let (w, h) = (hi.x - lo.x, hi.y - lo.y);
    let half = 0.5 * (w.max(h * 1.2)) + 2.0;
    let centre = 0.5 * (lo + hi);
    let (xr, yr) = (
        centre.x - half..centre.x + half,
        centre.y - half / 1.2..centre.y + half / 1.2,
    );
    let mut chart = ChartBuilder::on(&area)
        .caption(&plot.title, (FONT, 22))
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(45)
        .build_cartesian_2d(xr, yr)?;
    chart
        .configure_mesh()
        .light_line_style(WHITE)
        .x_desc("x (m)")
        .y_desc("y (m)")
        .draw()?;
    if !plot.true_path.is_empty() {
        chart
            .draw_series(LineSeries::new(
                plot.true_path.iter().map(|p| (p.x, p.y)),
                RGBColor(150, 150, 150).stroke_width(2),
            ))?
            .label("true trajectory")
            .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], RGBColor(150, 150, 150)));
    }
    if !plot.path.is_empty() {
        chart
            .draw_series(LineSeries::new(
                plot.path.iter().map(|p| (p.x, p.y)),
                RED.stroke_width(1),
            ))?
            .label("estimated trajectory")
            .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], RED));
    }
    let grey = RGBColor(90, 90, 90);
    let truth = chart.draw_series(plot.truth.iter().map(|c| {
        Circle::new(
            (c.position.x, c.position.y),
            5,
            rgb(c.color).stroke_width(1),
        )
    }))?;
    if !plot.truth.is_empty() {
        truth
            .label("true cone")
            .legend(move |(x, y)| Circle::new((x + 10, y), 5, grey.stroke_width(1)));
    }
    // 1σ ellipses of the mapped cones' covariances, and each mapped cone's
    // error to the nearest true cone (within a metre), both ×ARROW_SCALE.
    let ellipse = RGBColor(120, 120, 120).mix(0.6);
    let ellipses: Vec<_> = plot
        .map
        .iter()
        .filter_map(|c| {
            let points = ellipse_points(&c.covariance, ARROW_SCALE)?;
            let around = points
                .iter()
                .map(|p| (c.position.x + p.x, c.position.y + p.y));
            Some(PathElement::new(
                around.collect::<Vec<_>>(),
                ellipse.stroke_width(1),
            ))
        })
        .collect();
    if !ellipses.is_empty() {
        chart
            .draw_series(ellipses)?
            .label(format!("1σ of a mapped cone, ×{ARROW_SCALE}"))
            .legend(move |(x, y)| Circle::new((x + 10, y), 5, ellipse.stroke_width(1)));
    }
    let arrows: Vec<_> =
        plot.map
            .iter()
            .filter_map(|c| {
                let nearest =
                    plot.truth.iter().map(|t| t.position).min_by(|a, b| {
                        (a - c.position).norm().total_cmp(&(b - c.position).norm())
                    })?;
                let error = c.position - nearest;
                (error.norm() <= 1.0).then_some([
                    (nearest.x, nearest.y),
                    (
                        nearest.x + ARROW_SCALE * error.x,
                        nearest.y + ARROW_SCALE * error.y,
                    ),
                ])
            })
            .collect();
    if !arrows.is_empty() {
        chart
            .draw_series(
                arrows
                    .iter()
                    .map(|&[p, q]| PathElement::new(vec![p, q], BLACK.stroke_width(1))),
            )?
            .label(format!("map error, ×{ARROW_SCALE}"))
            .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], BLACK));
    }
    let map = chart.draw_series(
        plot.map
            .iter()
            .map(|c| Circle::new((c.position.x, c.position.y), 2, rgb(c.color).filled())),
    )?;
    if !plot.map.is_empty() {
        map.label("mapped cone")
            .legend(move |(x, y)| Circle::new((x + 10, y), 2, grey.filled()));
    }
    finish(&mut chart, SeriesLabelPosition::UpperLeft)
}

/// Points of the ellipse xᵀΣ⁻¹x = k², `None` for a covariance that is not
/// positive definite (or zero, as a map without variances).
fn ellipse_points(sigma: &nalgebra::Matrix2<f64>, k: f64) -> Option<Vec<Vector2<f64>>> {
    let l = sigma.cholesky()?.l();
    Some(
        (0..=36)
            .map(|i| {
                let a = f64::from(i) * std::f64::consts::TAU / 36.0;
                l * Vector2::new(a.cos(), a.sin()) * k
            })
            .collect(),
    )
}

/// The trajectory's position error over time, in a panel of its own.
fn draw_errors<DB: DrawingBackend>(
    errors: &[(f64, f64)],
    area: &DrawingArea<DB, Shift>,
) -> Result<(), Box<dyn std::error::Error>>
where
    DB::ErrorType: 'static,
{
    let t_end = errors.iter().map(|e| e.0).fold(f64::MIN, f64::max);
    let t_start = errors.iter().map(|e| e.0).fold(f64::MAX, f64::min);
    let top = errors.iter().map(|e| e.1).fold(0.0, f64::max).max(1e-3) * 1.1;
    let mut chart = ChartBuilder::on(area)
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(45)
        .build_cartesian_2d(t_start..t_end.max(t_start + 1e-3), 0.0..top)?;
    chart
        .configure_mesh()
        .light_line_style(WHITE)
        .x_desc("time (s)")
        .y_desc("position error (m)")
        .draw()?;
    chart.draw_series(LineSeries::new(errors.iter().copied(), RED.stroke_width(1)))?;
    Ok(())
}

/// Curves of y against x, one per named series.
pub struct LinePlot<'a> {
    /// Title above the plot.
    pub title: &'a str,
    /// Axis descriptions.
    pub x_desc: &'a str,
    /// See `x_desc`.
    pub y_desc: &'a str,
    /// (name, points) per curve.
    pub series: &'a [(String, Vec<(f64, f64)>)],
}

/// Writes a line plot to `path` (`.png` for a bitmap, otherwise SVG).
pub fn draw_lines(plot: &LinePlot, path: &Path) -> Result<(), String> {
    render(plot, path)
}

impl Drawing for LinePlot<'_> {
    const SIZE: (u32, u32) = (900, 560);

    fn draw_on<DB: DrawingBackend>(
        &self,
        area: DrawingArea<DB, Shift>,
    ) -> Result<(), Box<dyn std::error::Error>>
    where
        DB::ErrorType: 'static,
    {
        lines_on(self, area)
    }
}

fn lines_on<DB: DrawingBackend>(
    plot: &LinePlot,
    area: DrawingArea<DB, Shift>,
) -> Result<(), Box<dyn std::error::Error>>
where
    DB::ErrorType: 'static,
{
    area.fill(&WHITE)?;
    let all = plot.series.iter().flat_map(|(_, s)| s.iter());
    let (mut x0, mut x1, mut y1) = (f64::INFINITY, f64::NEG_INFINITY, 0.0f64);
    for &(x, y) in all.filter(|(x, y)| x.is_finite() && y.is_finite()) {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y1 = y1.max(y);
    }
    if x0 >= x1 || !x0.is_finite() {
        (x0, x1) = if x0.is_finite() {
            (x0 - 1.0, x0 + 1.0)
        } else {
            (0.0, 1.0)
        };
    }
    let y1 = if y1 > 0.0 { 1.1 * y1 } else { 1.0 };
    let mut chart = ChartBuilder::on(&area)
        .caption(plot.title, (FONT, 20))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(55)
        .build_cartesian_2d(x0..x1, 0.0..y1)?;
    chart
        .configure_mesh()
        .x_desc(plot.x_desc)
        .y_desc(plot.y_desc)
        .draw()?;
    for (k, (name, points)) in plot.series.iter().enumerate() {
        let color = Palette99::pick(k).to_rgba();
        chart
            .draw_series(LineSeries::new(
                points.iter().copied(),
                color.stroke_width(2),
            ))?
            .label(name)
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], color.stroke_width(2)));
        chart.draw_series(
            points
                .iter()
                .map(|&(x, y)| Circle::new((x, y), 3, color.filled())),
        )?;
    }
    finish(&mut chart, SeriesLabelPosition::UpperRight)
}

#[cfg(test)]
mod tests {
    use super::*;
    use cairn_slam::Color;

    /// Both plots in both formats, text included, with nothing from the
    /// system's fonts.
    #[test]
    fn plots_draw_as_svg_and_png() {
        let dir = std::env::temp_dir().join(format!("cairn-plot-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let cones = [Cone {
            position: Vector2::new(1.0, 2.0),
            color: Color::Blue,
            covariance: nalgebra::Matrix2::zeros(),
        }];
        let path = [Vector2::new(0.0, 0.0), Vector2::new(3.0, 1.0)];
        let map = MapPlot {
            title: "map".into(),
            truth: &cones,
            map: &cones,
            true_path: &path,
            path: &path,
            errors: &[(0.0, 0.1), (1.0, 0.2)],
        };
        let series = [("errors".to_string(), vec![(0.0, 1.0), (1.0, 0.5)])];
        let lines = LinePlot {
            title: "lines",
            x_desc: "x",
            y_desc: "y",
            series: &series,
        };
        for ext in ["svg", "png"] {
            let (a, b) = (
                dir.join(format!("map.{ext}")),
                dir.join(format!("lines.{ext}")),
            );
            draw(&map, &a).unwrap();
            draw_lines(&lines, &b).unwrap();
            for file in [a, b] {
                let bytes = std::fs::read(&file).unwrap();
                assert!(bytes.len() > 1000, "{}", file.display());
            }
        }
        let svg = std::fs::read_to_string(dir.join("map.svg")).unwrap();
        assert!(svg.contains("mapped cone") && svg.contains("x (m)"));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
