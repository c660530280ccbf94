//! What the scene shows, apart from its encoding: the force scales' colours and shades,
//! the node and support markers' colours and sizes, line widths, the legend's place and its
//! numbers.

use crate::model::Model;
use foxglove::messages::{ArrowPrimitive, Color, Pose, Quaternion};
use nalgebra::Vector3;

/// An opaque colour of red, green and blue in 0..=1.
const fn opaque(r: f64, g: f64, b: f64) -> Color {
    Color { r, g, b, a: 1.0 }
}

/// Line widths [px], independent of zoom so that any model size reads well.
pub(super) const STRUT_WIDTH: f64 = 6.0;
pub(super) const CABLE_WIDTH: f64 = 2.0;
/// A member whose |force| is below this fraction of the step's largest |force| is slack.
pub(super) const SLACK_FRACTION: f64 = 1e-6;
/// Shades of each force scale: a member's shade is ⌈LEVELS · |N| / max |N|⌉, the maximum
/// taken over the step's members of the same sign.
pub(super) const LEVELS: usize = 4;
/// Node sphere diameter as a fraction of the median member length of the model.
const NODE_SIZE: f64 = 0.05;
/// Support cube edge as a multiple of the node sphere diameter.
pub(super) const SUPPORT_SIZE: f64 = 1.6;
/// Highlighted struts: a magenta apart from the force scales, node and support colours.
pub(super) const MAGENTA: Color = opaque(0.85, 0.0, 0.75);
/// Legend font height [px].
pub(super) const LEGEND_FONT: f64 = 14.0;
pub(super) const RED: Color = opaque(0.85, 0.10, 0.10);
pub(super) const BLUE: Color = opaque(0.10, 0.30, 0.90);
/// Slack members, and where the force scales start: a mid grey, so that a faint force is
/// still seen on Foxglove's light theme.
pub(super) const GREY: Color = opaque(0.55, 0.55, 0.55);
pub(super) const GOLD: Color = opaque(0.95, 0.70, 0.10);
pub(super) const GREEN: Color = opaque(0.10, 0.65, 0.25);
pub(super) const PURPLE: Color = opaque(0.60, 0.30, 0.80);
/// Contact forces: an orange apart from the force scales and the highlight.
pub(super) const ORANGE: Color = opaque(1.0, 0.45, 0.0);
/// The longest contact arrow (the step's largest contact force) in node diameters.
const ARROW_NODES: f64 = 4.0;
/// Legend text: a teal of relative luminance 0.18, 4.6:1 against both black and white
/// (WCAG's 4.5:1 for text), readable on Foxglove's dark and light themes alike.
pub(super) const TEXT: Color = opaque(0.0, 0.515, 0.515);

/// Colour of a line state: 0 slack (grey), 1..=LEVELS tension (grey-red to full red),
/// LEVELS+1..=2·LEVELS compression (grey-blue to full blue).
pub(super) fn state_colour(state: usize) -> Color {
    if state == 0 {
        return GREY;
    }
    let (full, level) = if state <= LEVELS { (RED, state) } else { (BLUE, state - LEVELS) };
    let s = level as f64 / LEVELS as f64;
    let mix = |w: f64, c: f64| s * c + (1.0 - s) * w;
    Color {
        r: mix(GREY.r, full.r),
        g: mix(GREY.g, full.g),
        b: mix(GREY.b, full.b),
        a: 1.0,
    }
}

/// The shade of |force| on a scale whose top is `max` (> 0): 1..=LEVELS.
pub(super) fn level(force: f64, max: f64) -> usize {
    ((LEVELS as f64 * force.abs() / max).ceil() as usize).clamp(1, LEVELS)
}

/// `x` with three significant digits, plainly where that reads well.
pub(super) fn sig3(x: f64) -> String {
    let a = x.abs();
    if a == 0.0 || !a.is_finite() {
        format!("{x}")
    } else if (1e-2..1e5).contains(&a) {
        let decimals = (2 - a.log10().floor() as i32).max(0) as usize;
        format!("{x:.decimals$}")
    } else {
        format!("{x:.2e}")
    }
}

/// Node sphere diameter [m]: [`NODE_SIZE`] times the median member length of the model's
/// initial shape (a fraction of its extent without members, 0.05 m for a single point).
pub(super) fn node_size(model: &Model) -> f64 {
    let xyz: Vec<_> = model.positions();
    let mut lengths: Vec<f64> = model
        .members
        .iter()
        .map(|m| (xyz[m.nodes[1]] - xyz[m.nodes[0]]).norm())
        .filter(|l| *l > 0.0 && l.is_finite())
        .collect();
    lengths.sort_by(f64::total_cmp);
    if let Some(&median) = lengths.get(lengths.len() / 2) {
        return NODE_SIZE * median;
    }
    let (lo, hi) = bounds(&xyz);
    let extent = (hi - lo).norm();
    if extent > 0.0 && extent.is_finite() {
        0.02 * extent
    } else {
        0.05
    }
}

fn bounds(xyz: &[Vector3<f64>]) -> (Vector3<f64>, Vector3<f64>) {
    let lo = xyz.iter().fold(Vector3::repeat(f64::INFINITY), |a, p| a.inf(p));
    let hi = xyz.iter().fold(Vector3::repeat(f64::NEG_INFINITY), |a, p| a.sup(p));
    (lo, hi)
}

/// Above the middle of the shape's top, clear of it by a tenth of its extent (at least
/// four node diameters).
pub(super) fn legend_position(xyz: &[Vector3<f64>], node_size: f64) -> Vector3<f64> {
    if xyz.is_empty() {
        return Vector3::zeros();
    }
    let (lo, hi) = bounds(xyz);
    let clear = (0.1 * (hi - lo).norm()).max(4.0 * node_size);
    Vector3::new(0.5 * (lo.x + hi.x), 0.5 * (lo.y + hi.y), hi.z + clear)
}

/// A contact as the replay draws it: where, along which unit normal, and how hard [N].
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct ContactArrow {
    pub(super) point: Vector3<f64>,
    pub(super) normal: Vector3<f64>,
    pub(super) force: f64,
}

/// Orange arrows from each contact point along its normal (the force on the
/// higher-numbered strut, or on the node from the ground), their lengths in proportion to
/// the forces, the largest `ARROW_NODES` node diameters (`node_size`) long.
pub(super) fn contact_arrows(contacts: &[ContactArrow], node_size: f64) -> Vec<ArrowPrimitive> {
    let largest = contacts.iter().map(|c| c.force).fold(0.0, f64::max);
    if !(largest > 0.0) {
        return Vec::new();
    }
    contacts
        .iter()
        .map(|c| {
            let length = ARROW_NODES * node_size * c.force / largest;
            ArrowPrimitive {
                pose: Some(Pose {
                    position: Some(foxglove::messages::Vector3 {
                        x: c.point.x,
                        y: c.point.y,
                        z: c.point.z,
                    }),
                    orientation: Some(along(c.normal)),
                }),
                shaft_length: 0.7 * length,
                shaft_diameter: 0.15 * node_size,
                head_length: 0.3 * length,
                head_diameter: 0.4 * node_size,
                color: Some(ORANGE),
            }
        })
        .collect()
}

/// The rotation taking +x (an arrow's direction) to unit vector `n`: about x × n by the
/// angle between them (half-angle quaternion (1 + x·n, x × n), normalised; about z when n
/// is −x).
fn along(n: Vector3<f64>) -> Quaternion {
    let (w, axis) = (1.0 + n.x, Vector3::x().cross(&n));
    let norm = (w * w + axis.norm_squared()).sqrt();
    if norm < 1e-12 {
        return Quaternion {
            x: 0.0,
            y: 0.0,
            z: 1.0,
            w: 0.0,
        };
    }
    Quaternion {
        x: axis.x / norm,
        y: axis.y / norm,
        z: axis.z / norm,
        w: w / norm,
    }
}
