//! Pictures of a pose graph from above: its poses joined by odometry, loop
//! closures in another colour, landmarks as dots, and optionally a second
//! estimate of the same graph (the initial one, say) beneath it. SVG or PNG
//! by the file's extension.

use crate::plot::{Drawing, FONT, finish, render};
use cairn_core::Graph;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

/// What a graph looks like from above, in the xy-plane.
#[derive(Clone, Debug, Default)]
pub struct GraphPicture {
    /// Edges between poses next to each other in id order (landmark ids
    /// between them do not count).
    pub odometry: Vec<[(f64, f64); 2]>,
    /// Other edges between two poses.
    pub loop_closures: Vec<[(f64, f64); 2]>,
    /// Points (XY and XYZ vertices).
    pub landmarks: Vec<(f64, f64)>,
}

/// The picture of `graph`: SE2 and SE3 poses, XY and XYZ points; vertices of
/// other types and edges on more than two vertices are left out.
pub fn picture(graph: &Graph) -> GraphPicture {
    let place = |index: usize| {
        let v = graph.vertex(index);
        matches!(v.kind.name, "SE2" | "SE3" | "XY" | "XYZ").then(|| (v.params[0], v.params[1]))
    };
    let is_pose = |index: usize| matches!(graph.vertex(index).kind.name, "SE2" | "SE3");
    let mut out = GraphPicture {
        landmarks: graph
            .vertices()
            .filter(|v| matches!(v.kind.name, "XY" | "XYZ"))
            .map(|v| (v.params[0], v.params[1]))
            .collect(),
        ..Default::default()
    };
    // Each pose's place in id order.
    let mut poses: Vec<(i64, usize)> = graph
        .vertices()
        .filter(|v| is_pose(v.index))
        .map(|v| (v.id, v.index))
        .collect();
    poses.sort_unstable();
    let mut rank = vec![usize::MAX; graph.num_vertices()];
    for (r, &(_, index)) in poses.iter().enumerate() {
        rank[index] = r;
    }
    for edge in graph.edges() {
        let &[a, b] = edge.vertices() else { continue };
        if !(is_pose(a) && is_pose(b)) {
            continue;
        }
        let (Some(p), Some(q)) = (place(a), place(b)) else {
            continue;
        };
        if rank[a].abs_diff(rank[b]) == 1 {
            out.odometry.push([p, q]);
        } else {
            out.loop_closures.push([p, q]);
        }
    }
    out
}

/// Writes `main` (and the odometry of `beneath` in grey, with its label)
/// to `path`: `.png` for a bitmap, otherwise SVG.
pub fn draw_graph(
    title: &str,
    main: &GraphPicture,
    beneath: Option<(&GraphPicture, &str)>,
    path: &Path,
) -> Result<(), String> {
    render(
        &GraphDrawing {
            title,
            main,
            beneath,
        },
        path,
    )
}

struct GraphDrawing<'a> {
    title: &'a str,
    main: &'a GraphPicture,
    beneath: Option<(&'a GraphPicture, &'a str)>,
}

impl Drawing for GraphDrawing<'_> {
    const SIZE: (u32, u32) = (1000, 900);

    fn draw_on<DB: DrawingBackend>(
        &self,
        area: DrawingArea<DB, Shift>,
    ) -> Result<(), Box<dyn std::error::Error>>
    where
        DB::ErrorType: 'static,
    {
        draw_on(self.title, self.main, self.beneath, area)
    }
}

/// The square around every point of the pictures, with a margin.
fn extent<'a>(pictures: impl Iterator<Item = &'a GraphPicture>) -> ((f64, f64), (f64, f64)) {
    let (mut lo, mut hi) = (
        (f64::INFINITY, f64::INFINITY),
        (f64::NEG_INFINITY, f64::NEG_INFINITY),
    );
    for p in pictures {
        let segments = p.odometry.iter().chain(&p.loop_closures).flatten();
        for &(x, y) in segments.chain(&p.landmarks) {
            lo = (lo.0.min(x), lo.1.min(y));
            hi = (hi.0.max(x), hi.1.max(y));
        }
    }
    if !(lo.0.is_finite() && hi.0.is_finite()) {
        return ((-1.0, 1.0), (-1.0, 1.0));
    }
    let half = 0.55 * (hi.0 - lo.0).max(hi.1 - lo.1).max(1e-9);
    let centre = (0.5 * (lo.0 + hi.0), 0.5 * (lo.1 + hi.1));
    // Room above for the legend.
    (
        (centre.0 - half, centre.0 + half),
        (centre.1 - half, centre.1 + 1.2 * half),
    )
}

fn draw_on<DB: DrawingBackend>(
    title: &str,
    main: &GraphPicture,
    beneath: Option<(&GraphPicture, &str)>,
    area: DrawingArea<DB, Shift>,
) -> Result<(), Box<dyn std::error::Error>>
where
    DB::ErrorType: 'static,
{
    area.fill(&WHITE)?;
    let (xr, yr) = extent(std::iter::once(main).chain(beneath.map(|(p, _)| p)));
    let mut chart = ChartBuilder::on(&area)
        .caption(title, (FONT, 22))
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(50)
        .build_cartesian_2d(xr.0..xr.1, yr.0..yr.1)?;
    chart
        .configure_mesh()
        .light_line_style(WHITE)
        .x_desc("x")
        .y_desc("y")
        .draw()?;
    let segments = |s: &[[(f64, f64); 2]], style: ShapeStyle| {
        s.iter()
            .map(move |&[p, q]| PathElement::new(vec![p, q], style))
            .collect::<Vec<_>>()
    };
    if let Some((picture, label)) = beneath {
        let grey = RGBColor(185, 185, 185);
        chart
            .draw_series(segments(&picture.odometry, grey.stroke_width(1)))?
            .label(label.to_string())
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], grey));
    }
    let loops = RGBColor(230, 120, 40);
    if !main.loop_closures.is_empty() {
        chart
            .draw_series(segments(
                &main.loop_closures,
                loops.mix(0.5).stroke_width(1),
            ))?
            .label(format!("loop closures ({})", main.loop_closures.len()))
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], loops));
    }
    let odometry = RGBColor(30, 70, 190);
    if !main.odometry.is_empty() {
        chart
            .draw_series(segments(&main.odometry, odometry.stroke_width(1)))?
            .label(format!("odometry ({})", main.odometry.len()))
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], odometry));
    }
    if !main.landmarks.is_empty() {
        let green = RGBColor(20, 150, 60);
        chart
            .draw_series(
                main.landmarks
                    .iter()
                    .map(|&p| Circle::new(p, 2, green.filled())),
            )?
            .label(format!("landmarks ({})", main.landmarks.len()))
            .legend(move |(x, y)| Circle::new((x + 10, y), 3, green.filled()));
    }
    finish(&mut chart, SeriesLabelPosition::UpperLeft)
}

#[cfg(test)]
mod tests {
    use super::*;
    use cairn_core::nalgebra::{Matrix2, Matrix3, Vector2};
    use cairn_core::{EdgeSE2, EdgeSE2XY, SE2};

    #[test]
    fn odometry_follows_the_poses_id_order_and_landmarks_are_dots() {
        let mut g = Graph::new();
        // Poses 0, 1 and 3 with a landmark (2) between their ids.
        for (id, x) in [(0, 0.0), (1, 1.0), (3, 2.0)] {
            g.add_vertex(id, SE2::new(x, 0.0, 0.0)).unwrap();
        }
        g.add_vertex(2, Vector2::new(1.0, 5.0)).unwrap();
        let step = EdgeSE2::new(SE2::new(1.0, 0.0, 0.0));
        g.add_edge(0, 1, step.clone(), Matrix3::identity()).unwrap();
        g.add_edge(1, 3, step.clone(), Matrix3::identity()).unwrap();
        g.add_edge(0, 3, step, Matrix3::identity()).unwrap();
        g.add_edge(
            1,
            2,
            EdgeSE2XY::new(Vector2::new(0.0, 5.0)),
            Matrix2::identity(),
        )
        .unwrap();
        let p = picture(&g);
        assert_eq!(
            p.odometry,
            vec![[(0.0, 0.0), (1.0, 0.0)], [(1.0, 0.0), (2.0, 0.0)]]
        );
        assert_eq!(p.loop_closures, vec![[(0.0, 0.0), (2.0, 0.0)]]);
        assert_eq!(p.landmarks, vec![(1.0, 5.0)]);
    }
}
