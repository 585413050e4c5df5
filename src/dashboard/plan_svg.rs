//! The face plan drawn as SVG: points in the best-fit plane of the face ([`super::face_plan`]),
//! coloured by alert level, stable points as triangles, displacement vectors exaggerated, with
//! the exaggeration and two scale bars (plan metres, displacement millimetres). The component
//! out of the face (along its normal, towards the side the normal points to) is drawn as a ring
//! around the point whose radius is that displacement on the vectors' scale (solid blue towards
//! the cameras, dashed brown into the face), so a block moving mostly out of the face shows as
//! plainly as one sliding down it, and is written under each name as "⊥ ±x.x mm".

use maud::{html, Markup};

use super::face_plan::{nice_floor, FacePlane};
use super::layout::{level_class, seg};
use super::plan_labels::{shown, LabelInput, Shown, DESKTOP, PHONE};
use cliffwatch_core::analysis::site_frame::{NormalSource, SiteFrame};
use cliffwatch_core::analysis::AlertLevel;

/// One point to draw.
#[derive(Debug, Clone)]
pub struct PlanPoint {
    /// Name (label and link).
    pub name: String,
    /// Latest coordinates, site frame, m.
    pub xyz: [f64; 3],
    /// Latest displacement (dx, dy, dz) in mm, when there is one.
    pub d_mm: Option<[f64; 3]>,
    /// Highest active alert level of the point.
    pub level: Option<AlertLevel>,
    /// A stable (datum) point.
    pub stable: bool,
    /// The latest epoch's minimum detectable displacement in the worst direction, mm (80 %
    /// power at the site's confidence; see [`super::sensitivity`]), shown in the tooltip.
    pub mdd_mm: Option<f64>,
}

const W: f64 = 900.0;
const H: f64 = 520.0;
const PAD: f64 = 48.0;

/// The plan of `site`'s points in its declared `frame`, with its legend (a figure; the legend is
/// HTML so it wraps on a phone); a note instead when fewer than three points span a plane.
pub fn face_plan(site: &str, frame: &SiteFrame, points: &[PlanPoint]) -> Markup {
    let xyz: Vec<[f64; 3]> = points.iter().map(|p| p.xyz).collect();
    let stable: Vec<[f64; 3]> = points.iter().filter(|p| p.stable).map(|p| p.xyz).collect();
    let Some(plane) = FacePlane::fit(frame, &stable, &xyz) else {
        return html! { p.note { "The face plan needs at least three points that span a plane, not within 10° of horizontal (the site's up axis is " (SiteFrame::describe(frame.up)) ")." } };
    };
    let uv: Vec<[f64; 2]> = xyz.iter().map(|p| plane.project(*p)).collect();
    let (mut u0, mut u1, mut v0, mut v1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for p in &uv {
        u0 = u0.min(p[0]);
        u1 = u1.max(p[0]);
        v0 = v0.min(p[1]);
        v1 = v1.max(p[1]);
    }
    let extent = (u1 - u0).max(v1 - v0).max(1e-3);
    let scale = ((W - 2.0 * PAD) / (u1 - u0).max(1e-3)).min((H - 2.0 * PAD) / (v1 - v0).max(1e-3));
    let sx = |u: f64| PAD + (u - u0) * scale;
    let sy = |v: f64| H - PAD - (v - v0) * scale;
    // Exaggeration: the largest displacement, in the face or out of it, drawn as 15 % of the
    // plan's extent.
    let max_d_m = points
        .iter()
        .filter_map(|p| p.d_mm)
        .map(|d| {
            let v = plane.project_vector(d);
            v[0].hypot(v[1]).max(plane.out_of_plane(d).abs()) / 1000.0
        })
        .fold(0.0f64, f64::max);
    let exaggeration = if max_d_m > 0.0 {
        nice_floor(0.15 * extent / max_d_m).max(1.0)
    } else {
        1.0
    };
    let bar_m = nice_floor(extent / 5.0);
    let bar_px = bar_m * scale;
    let bar_mm = bar_m * 1000.0 / exaggeration;
    let normals: Vec<Option<String>> = points
        .iter()
        .map(|p| {
            let n = plane.out_of_plane(p.d_mm?);
            (n.abs() >= 0.05).then(|| format!("⊥ {n:+.1} mm"))
        })
        .collect();
    // Each point's out-of-face ring: radius in plan units and whether towards the cameras.
    let rings: Vec<Option<(f64, bool)>> = points
        .iter()
        .map(|p| {
            let n = plane.out_of_plane(p.d_mm?);
            let r = n.abs() / 1000.0 * exaggeration * scale;
            (r > 1.5).then_some((r, n > 0.0))
        })
        .collect();
    // Each point's arrow in plan units (y down), when long enough to draw.
    let arrows: Vec<Option<(f64, f64)>> = points
        .iter()
        .map(|p| {
            let v = plane.project_vector(p.d_mm?);
            let (dx, dy) = (
                v[0] / 1000.0 * exaggeration * scale,
                v[1] / 1000.0 * exaggeration * scale,
            );
            (dx.hypot(dy) > 1.5).then_some((dx, -dy))
        })
        .collect();
    let labels: Vec<LabelInput<'_>> = points
        .iter()
        .zip(&uv)
        .zip(&normals)
        .zip(&arrows)
        .map(|(((p, q), n), a)| LabelInput {
            x: sx(q[0]),
            y: sy(q[1]),
            name: &p.name,
            normal: n.as_deref(),
            level: p.level,
            stable: p.stable,
            arrow: *a,
        })
        .collect();
    let (wide, narrow) = (shown(&labels, &DESKTOP), shown(&labels, &PHONE));
    // The classes that hide a text in the layout whose labels leave it out.
    let crowded = |i: usize, least: Shown| {
        let hidden = |s: Shown| match least {
            Shown::Full => s != Shown::Full,
            _ => s == Shown::Hidden,
        };
        match (hidden(wide[i]), hidden(narrow[i])) {
            (false, false) => "",
            (true, false) => " crowded-wide",
            (false, true) => " crowded-narrow",
            (true, true) => " crowded-wide crowded-narrow",
        }
    };
    let any_left_out = wide.iter().chain(&narrow).any(|k| *k != Shown::Full);
    html! {
        figure.plan {
            svg.plan viewBox={ "0 0 " (W) " " (H) } role="img" aria-label="face plan" xmlns="http://www.w3.org/2000/svg" {
                defs {
                    marker id="arrow" viewBox="0 0 10 10" refX="9" refY="5" markerWidth="6" markerHeight="6" orient="auto-start-reverse" {
                        path d="M 0 0 L 10 5 L 0 10 z" fill="#333" {}
                    }
                }
                @for (i, (p, q)) in points.iter().zip(&uv).enumerate() {
                    @let (x, y) = (sx(q[0]), sy(q[1]));
                    @let class = level_class(p.level);
                    a href={ "/sites/" (seg(site)) "/points/" (seg(&p.name)) } {
                        @if let Some((r, toward)) = rings[i] {
                            circle class={ "out " (if toward { "toward" } else { "into" }) } cx=(fmt(x)) cy=(fmt(y)) r=(fmt(r)) {}
                        }
                        @if let Some((dx, dy)) = arrows[i] {
                            line.vector x1=(fmt(x)) y1=(fmt(y)) x2=(fmt(x + dx)) y2=(fmt(y + dy)) marker-end="url(#arrow)" {}
                        }
                        @if p.stable {
                            polygon class={ "pt stable " (class) } points={ (fmt(x)) "," (fmt(y - 8.0)) " " (fmt(x - 7.0)) "," (fmt(y + 5.0)) " " (fmt(x + 7.0)) "," (fmt(y + 5.0)) } {
                                title { (p.name) " (stable)" (out_of_face(&normals[i])) (detectable(p.mdd_mm)) }
                            }
                        } @else {
                            circle class={ "pt " (class) } cx=(fmt(x)) cy=(fmt(y)) r="6" {
                                title { (p.name) (out_of_face(&normals[i])) (detectable(p.mdd_mm)) }
                            }
                        }
                        text class={ "label" (crowded(i, Shown::NameOnly)) } x=(fmt(x + 9.0)) y=(fmt(y - 7.0)) { (p.name) }
                        @if let Some(n) = &normals[i] {
                            text class={ "normal" (crowded(i, Shown::Full)) } x=(fmt(x + 9.0)) y=(fmt(y + 12.0)) { (n) }
                        }
                    }
                }
                g.scale {
                    line x1=(fmt(PAD)) y1=(fmt(H - 14.0)) x2=(fmt(PAD + bar_px)) y2=(fmt(H - 14.0)) {}
                    text x=(fmt(PAD)) y=(fmt(H - 22.0)) {
                        (short(bar_m)) " m · " (short(bar_mm)) " mm"
                    }
                }
            }
            figcaption.legend {
                "Scale bar: " (short(bar_m)) " m on the face, " (short(bar_mm)) " mm of displacement; vectors × "
                (short(exaggeration)) ". Along the face →, height ↑; ⊥: displacement out of the face (mm), + towards the cameras, "
                "drawn as a ring of that radius on the vectors' scale: " span.ring.toward { "solid blue" } " towards the cameras, "
                span.ring.into { "dashed brown" } " into the face. "
                span.frame { "Up is " (SiteFrame::describe(frame.up)) "; out of the face is " (SiteFrame::describe(plane.axes.out)) ", "
                    (match plane.axes.source {
                        NormalSource::Declared => "as the site declares",
                        NormalSource::StablePoints => "from the stable points' plane",
                        NormalSource::AllPoints => "from the points' plane (fewer than three stable points)",
                    }) "." }
                @if any_left_out { " Names and out-of-face lines that would overlap are left out; point at a mark for them." }
            }
        }
    }
}

/// The tooltip's out-of-face clause: " · ⊥ +x.x mm" (empty when none is drawn).
fn out_of_face(normal: &Option<String>) -> String {
    normal.as_ref().map_or(String::new(), |n| format!(" · {n}"))
}

/// The tooltip's sensitivity clause: " · detects ≥ x.x mm" (empty without an MDD).
fn detectable(mdd_mm: Option<f64>) -> String {
    mdd_mm.map_or(String::new(), |m| {
        format!(" · detects movement ≥ {m:.1} mm")
    })
}

fn fmt(x: f64) -> String {
    format!("{x:.1}")
}

fn short(x: f64) -> String {
    if x >= 100.0 || x == x.round() {
        format!("{x:.0}")
    } else {
        format!("{}", (x * 1000.0).round() / 1000.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_plan_names_every_point_and_escapes_names() {
        let pts: Vec<PlanPoint> = (0..6)
            .map(|i| PlanPoint {
                name: if i == 0 {
                    "<script>x</script>".into()
                } else {
                    format!("T{i}")
                },
                xyz: [i as f64 * 2.0, 100.0, (i % 3) as f64 * 4.0],
                d_mm: Some([0.0, -3.0 * (i % 2) as f64, 1.0]),
                level: (i == 2).then_some(AlertLevel::Warning),
                stable: i == 5,
                mdd_mm: (i == 1).then_some(1.26),
            })
            .collect();
        let svg = face_plan("s<1>", &SiteFrame::default(), &pts).into_string();
        assert!(
            svg.contains("<title>T1 · ⊥ +3.0 mm · detects movement ≥ 1.3 mm</title>"),
            "{svg}"
        );
        assert!(svg.contains("<title>T2</title>"));
        for i in 1..6 {
            assert!(svg.contains(&format!(">T{i}</text>")), "T{i}");
        }
        assert!(svg.contains("&lt;script&gt;") && !svg.contains("<script>"));
        assert!(svg.contains("pt warning") && svg.contains("pt stable"));
        assert!(svg.contains("vectors ×"));
        // The face is the plane Y = 100: the 3 mm along −Y of the odd points is out of plane.
        assert!(
            svg.contains("⊥ +3.0 mm") || svg.contains("⊥ -3.0 mm"),
            "{svg}"
        );
        assert!(svg.contains("/sites/s%3C1%3E/points/T1"));
    }

    /// A block moving 83 mm out of the face and 46 mm down: its rings are larger than its
    /// arrows (the same scale), solid towards the cameras, and the legend says so.
    #[test]
    fn motion_out_of_the_face_is_drawn_as_plainly_as_in_it() {
        let pts: Vec<PlanPoint> = (0..6)
            .map(|i| PlanPoint {
                name: format!("T{i}"),
                xyz: [(i % 3) as f64 * 4.0, 100.0, (i / 3) as f64 * 4.0],
                d_mm: Some(if i < 3 {
                    [0.0, 0.0, 0.0]
                } else {
                    [0.0, -83.0, -46.0]
                }),
                level: None,
                stable: i < 3,
                mdd_mm: None,
            })
            .collect();
        let svg = face_plan("s", &SiteFrame::default(), &pts).into_string();
        let number = |tag: &str, attr: &str| -> Vec<f64> {
            svg.split(tag)
                .skip(1)
                .filter_map(|t| {
                    t.split(&format!("{attr}=\""))
                        .nth(1)?
                        .split('"')
                        .next()?
                        .parse()
                        .ok()
                })
                .collect()
        };
        let radii = number("<circle class=\"out ", "r");
        assert_eq!(radii.len(), 3, "{svg}");
        let (y1, y2) = (
            number("<line class=\"vector\"", "y1"),
            number("<line class=\"vector\"", "y2"),
        );
        assert_eq!(y1.len(), 3, "{svg}");
        for ((r, a), b) in radii.iter().zip(&y1).zip(&y2) {
            let arrow = (b - a).abs();
            assert!(*r > 1.5 * arrow, "ring {r} against arrow {arrow}");
            assert!(
                (r / arrow - 83.0 / 46.0).abs() < 0.1,
                "ring {r}, arrow {arrow}"
            );
        }
        assert!(svg.contains("class=\"out toward\"") || svg.contains("class=\"out into\""));
        assert!(
            svg.contains("drawn as a ring of that radius on the vectors' scale"),
            "{svg}"
        );
    }
}
