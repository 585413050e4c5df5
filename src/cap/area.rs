//! A site's warning area (where its warnings apply), as a site setting and in CAP's notation.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

/// The area a site's warnings concern, e.g. the road below the cliff: a description and, for
/// systems that map it, a polygon or a circle in WGS 84.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct SiteArea {
    /// Text naming the area (CAP `areaDesc`), e.g. "Route 42 below the Kamo cliff, km 3.2–3.6".
    #[schema(min_length = 1, max_length = 500, pattern = "^[^\\u0000]*$")]
    pub description: String,
    /// Closed ring of `[latitude, longitude]` pairs in degrees (WGS 84): at least 4 pairs, the
    /// last equal to the first.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(min_items = 4, max_items = 1000)]
    pub polygon: Option<Vec<[f64; 2]>>,
    /// A circle around a point.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub circle: Option<Circle>,
}

/// A circle in WGS 84.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Circle {
    /// Latitude of the centre in degrees (−90 to 90).
    #[schema(minimum = -90.0, maximum = 90.0)]
    pub latitude: f64,
    /// Longitude of the centre in degrees (−180 to 180).
    #[schema(minimum = -180.0, maximum = 180.0)]
    pub longitude: f64,
    /// Radius in kilometres (≥ 0).
    #[schema(minimum = 0.0, maximum = 20000.0)]
    pub radius_km: f64,
}

fn check_position(what: &str, lat: f64, lon: f64) -> Result<(), String> {
    if !(-90.0..=90.0).contains(&lat) || !(-180.0..=180.0).contains(&lon) {
        return Err(format!(
            "{what} ({lat}, {lon}): latitude −90 to 90 and longitude −180 to 180 degrees"
        ));
    }
    Ok(())
}

impl SiteArea {
    /// Checks the description, the ring (closed, ≥ 4 pairs, in range) and the circle; the
    /// message names the item at fault.
    pub fn validate(&self) -> Result<(), String> {
        let d = self.description.trim();
        if d.is_empty() || self.description.chars().count() > 500 {
            return Err("area.description: 1 to 500 characters".into());
        }
        if self.description.contains('\0') {
            return Err("area.description: the NUL character (U+0000) is not allowed".into());
        }
        if let Some(ring) = &self.polygon {
            if !(4..=1000).contains(&ring.len()) {
                return Err(format!(
                    "area.polygon: {} pairs; a closed ring needs 4 to 1000",
                    ring.len()
                ));
            }
            for (i, p) in ring.iter().enumerate() {
                check_position(&format!("area.polygon[{i}]"), p[0], p[1])?;
            }
            if ring.first() != ring.last() {
                return Err("area.polygon: the last pair must equal the first".into());
            }
        }
        if let Some(c) = &self.circle {
            check_position("area.circle", c.latitude, c.longitude)?;
            if !(0.0..=20_000.0).contains(&c.radius_km) {
                return Err(format!("area.circle.radius_km {}: 0 to 20000", c.radius_km));
            }
        }
        Ok(())
    }

    /// The ring in CAP notation: `lat,lon lat,lon …`.
    pub fn cap_polygon(&self) -> Option<String> {
        self.polygon.as_ref().map(|ring| {
            ring.iter()
                .map(|p| format!("{},{}", p[0], p[1]))
                .collect::<Vec<_>>()
                .join(" ")
        })
    }

    /// The circle in CAP notation: `lat,lon radius_km`.
    pub fn cap_circle(&self) -> Option<String> {
        self.circle
            .map(|c| format!("{},{} {}", c.latitude, c.longitude, c.radius_km))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square() -> Vec<[f64; 2]> {
        vec![
            [35.0, 139.0],
            [35.0, 139.01],
            [35.01, 139.01],
            [35.0, 139.0],
        ]
    }

    #[test]
    fn a_closed_ring_passes_and_prints_as_cap_pairs() {
        let a = SiteArea {
            description: "road".into(),
            polygon: Some(square()),
            circle: None,
        };
        assert_eq!(a.validate(), Ok(()));
        assert_eq!(
            a.cap_polygon().unwrap(),
            "35,139 35,139.01 35.01,139.01 35,139"
        );
    }

    #[test]
    fn open_rings_and_bad_positions_are_named() {
        let mut ring = square();
        ring[3] = [35.02, 139.0];
        let a = SiteArea {
            description: "road".into(),
            polygon: Some(ring),
            circle: None,
        };
        assert!(a.validate().unwrap_err().contains("last pair"));
        let b = SiteArea {
            description: "road".into(),
            polygon: None,
            circle: Some(Circle {
                latitude: 95.0,
                longitude: 0.0,
                radius_km: 1.0,
            }),
        };
        assert!(b.validate().unwrap_err().starts_with("area.circle"));
        let c = SiteArea {
            description: "  ".into(),
            polygon: None,
            circle: None,
        };
        assert!(c.validate().unwrap_err().contains("description"));
    }
}
