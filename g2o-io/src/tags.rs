//! The g2o record tags Cairn reads and writes.

/// SE2 pose: `VERTEX_SE2 id x y θ`.
pub const VERTEX_SE2: &str = "VERTEX_SE2";
/// 2D point: `VERTEX_XY id x y`.
pub const VERTEX_XY: &str = "VERTEX_XY";
/// SE3 pose: `VERTEX_SE3:QUAT id x y z qx qy qz qw`.
pub const VERTEX_SE3_QUAT: &str = "VERTEX_SE3:QUAT";
/// `EDGE_SE2 i j dx dy dθ` + 6 information values.
pub const EDGE_SE2: &str = "EDGE_SE2";
/// `EDGE_SE2_XY i l dx dy` + 3 information values.
pub const EDGE_SE2_XY: &str = "EDGE_SE2_XY";
/// `LANDMARK2 i l dx dy` + 3 information values; `l` in a separate id space.
pub const LANDMARK2: &str = "LANDMARK2";
/// `EDGE_PRIOR_SE2 i x y θ` + 6 information values.
pub const EDGE_PRIOR_SE2: &str = "EDGE_PRIOR_SE2";
/// `EDGE_SE3:QUAT i j x y z qx qy qz qw` + 21 information values.
pub const EDGE_SE3_QUAT: &str = "EDGE_SE3:QUAT";
/// `FIX id …`: hold the listed vertices constant.
pub const FIX: &str = "FIX";

/// Every tag above: a registered type cannot take one.
pub const ALL: [&str; 9] = [
    VERTEX_SE2,
    VERTEX_XY,
    VERTEX_SE3_QUAT,
    EDGE_SE2,
    EDGE_SE2_XY,
    LANDMARK2,
    EDGE_PRIOR_SE2,
    EDGE_SE3_QUAT,
    FIX,
];
