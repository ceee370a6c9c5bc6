//! What users look at: `solve --traj-out` trajectories (checked against the
//! written graph) and `cairn plot` pictures (read back).

use std::path::{Path, PathBuf};
use std::process::Command;

fn cairn(args: &[&str]) {
    let o = Command::new(env!("CARGO_BIN_EXE_cairn"))
        .args(args)
        .output()
        .expect("runs");
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
}

fn folder(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("cairn-traj-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Numbers of each line of a text file.
fn rows(path: &Path) -> Vec<Vec<f64>> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .map(|l| l.split_whitespace().map(|x| x.parse().unwrap()).collect())
        .collect()
}

/// (id, numbers) of the solved graph's vertex lines with this tag.
fn vertices(path: &Path, tag: &str) -> Vec<(f64, Vec<f64>)> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .filter(|l| l.starts_with(&format!("{tag} ")))
        .map(|l| {
            let v: Vec<f64> = l
                .split_whitespace()
                .skip(1)
                .map(|x| x.parse().unwrap())
                .collect();
            (v[0], v[1..].to_vec())
        })
        .collect()
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-9 * (1.0 + a.abs())
}

#[test]
fn se2_poses_as_tum_and_kitti() {
    let dir = folder("se2");
    let (graph, solved) = (dir.join("g.g2o"), dir.join("solved.g2o"));
    let (tum, kitti) = (dir.join("t.tum"), dir.join("t.kitti"));
    cairn(&["generate", "manhattan", "-n", "200", "-o", s(&graph)]);
    cairn(&[
        "solve",
        "-q",
        s(&graph),
        "-o",
        s(&solved),
        "--traj-out",
        s(&tum),
    ]);
    cairn(&[
        "solve",
        "-q",
        s(&graph),
        "--traj-out",
        s(&kitti),
        "--traj-format",
        "kitti",
    ]);
    let poses = vertices(&solved, "VERTEX_SE2");
    let (tum, kitti) = (rows(&tum), rows(&kitti));
    assert_eq!((tum.len(), kitti.len()), (poses.len(), poses.len()));
    for ((id, p), (t, k)) in poses.iter().zip(tum.iter().zip(&kitti)) {
        let (x, y, theta) = (p[0], p[1], p[2]);
        assert_eq!(t.len(), 8);
        assert_eq!(t[0], *id);
        assert!(close(t[1], x) && close(t[2], y) && t[3] == 0.0);
        // A turn about z by θ: q = (0, 0, sin θ/2, cos θ/2), up to sign.
        let (sin, cos) = (0.5 * theta).sin_cos();
        let sign = if (t[6] - sin).abs() + (t[7] - cos).abs() < 1e-6 {
            1.0
        } else {
            -1.0
        };
        assert!(close(t[6], sign * sin) && close(t[7], sign * cos) && t[4] == 0.0 && t[5] == 0.0);
        assert_eq!(k.len(), 12);
        assert!(close(k[0], theta.cos()) && close(k[1], -theta.sin()) && close(k[3], x));
        assert!(close(k[4], theta.sin()) && close(k[7], y) && close(k[10], 1.0));
    }
}

#[test]
fn se3_poses_and_no_landmarks() {
    let dir = folder("se3");
    let (graph, solved, tum) = (dir.join("g.g2o"), dir.join("solved.g2o"), dir.join("t.tum"));
    cairn(&["generate", "sphere", "-n", "100", "-o", s(&graph)]);
    cairn(&[
        "solve",
        "-q",
        s(&graph),
        "-o",
        s(&solved),
        "--traj-out",
        s(&tum),
    ]);
    let poses = vertices(&solved, "VERTEX_SE3:QUAT");
    let tum = rows(&tum);
    assert_eq!(tum.len(), poses.len());
    for ((id, p), t) in poses.iter().zip(&tum) {
        assert_eq!(t[0], *id);
        for k in 0..7 {
            // A quaternion and its negative are one rotation.
            assert!(
                close(t[k + 1], p[k]) || (k >= 3 && close(t[k + 1], -p[k])),
                "{t:?} {p:?}"
            );
        }
    }
    // Landmarks are not poses: a graph of one pose and a point writes one row.
    let small = dir.join("small.g2o");
    std::fs::write(
        &small,
        "VERTEX_SE2 0 0 0 0\nVERTEX_XY 1 1 0\nEDGE_SE2_XY 0 1 1 0 1 0 1\n",
    )
    .unwrap();
    let one = dir.join("one.tum");
    cairn(&["solve", "-q", s(&small), "--traj-out", s(&one)]);
    assert_eq!(rows(&one).len(), 1);
}

/// `cairn plot` draws a graph into SVG or PNG, with the initial estimate
/// beneath, and refuses other formats before reading anything.
#[test]
fn plot_writes_svg_and_png() {
    let dir = folder("plot");
    let (graph, solved) = (dir.join("g.g2o"), dir.join("solved.g2o"));
    cairn(&["generate", "manhattan", "-n", "300", "-o", s(&graph)]);
    cairn(&["solve", "-q", s(&graph), "-o", s(&solved)]);
    let (svg, png) = (dir.join("p.svg"), dir.join("p.png"));
    cairn(&["plot", s(&solved), "--compare", s(&graph), "-o", s(&svg)]);
    cairn(&["plot", s(&solved), "-o", s(&png), "--title", "manhattan"]);
    let text = std::fs::read_to_string(&svg).unwrap();
    assert!(text.starts_with("<svg"), "{}", &text[..100]);
    let edges = std::fs::read_to_string(&solved)
        .unwrap()
        .lines()
        .filter(|l| l.starts_with("EDGE_SE2 "))
        .count();
    let odometry: usize = text
        .split("odometry (")
        .nth(1)
        .unwrap()
        .split(')')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    let loops: usize = text
        .split("loop closures (")
        .nth(1)
        .unwrap()
        .split(')')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert_eq!(odometry, 299);
    assert_eq!(odometry + loops, edges);
    assert!(
        text.contains("g.g2o") && text.contains("solved.g2o"),
        "the legend and the title name the files"
    );
    let bytes = std::fs::read(&png).unwrap();
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
    // Width and height from the IHDR chunk.
    let be = |b: &[u8]| u32::from_be_bytes([b[0], b[1], b[2], b[3]]);
    assert_eq!((be(&bytes[16..20]), be(&bytes[20..24])), (1000, 900));
    let o = Command::new(env!("CARGO_BIN_EXE_cairn"))
        .args(["plot", s(&solved), "-o", s(&dir.join("p.pdf"))])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
}
