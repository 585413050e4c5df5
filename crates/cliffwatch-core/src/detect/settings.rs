//! A site's detection settings (issue 59, item 6): the target polarity and the range of target
//! diameters, as the site's settings and a folder's `epoch.json` give them; the folder's override
//! the site's field by field, and what neither gives is [`DetectOptions::default`].

use serde::{Deserialize, Serialize};

use super::{DetectOptions, Polarity};

/// Smallest diameter a setting may give, px.
pub const MIN_DIAMETER_PX: f64 = 1.0;
/// Largest diameter a setting may give, px.
pub const MAX_DIAMETER_PX: f64 = 1000.0;

/// Which targets to look for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "snake_case")]
pub enum PolarityChoice {
    /// Both polarities searched, the one that yields more targets kept.
    Auto,
    /// Bright targets on a darker background (retro-reflective with flash).
    Bright,
    /// Dark targets on a brighter background (printed dots).
    Dark,
}

impl PolarityChoice {
    /// `"auto"`, `"bright"` or `"dark"`.
    pub fn as_str(self) -> &'static str {
        match self {
            PolarityChoice::Auto => "auto",
            PolarityChoice::Bright => "bright",
            PolarityChoice::Dark => "dark",
        }
    }

    /// The detector's polarity (`None`: both searched).
    pub fn polarity(self) -> Option<Polarity> {
        match self {
            PolarityChoice::Auto => None,
            PolarityChoice::Bright => Some(Polarity::BrightOnDark),
            PolarityChoice::Dark => Some(Polarity::DarkOnBright),
        }
    }

    /// The choice of the detector's polarity option ([`PolarityChoice::polarity`] reversed).
    pub fn of(polarity: Option<Polarity>) -> PolarityChoice {
        match polarity {
            None => PolarityChoice::Auto,
            Some(Polarity::BrightOnDark) => PolarityChoice::Bright,
            Some(Polarity::DarkOnBright) => PolarityChoice::Dark,
        }
    }
}

/// Detection settings; every field optional (absent: the next source's, then the default).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct DetectionSettings {
    /// `auto` (default), `bright` or `dark`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub polarity: Option<PolarityChoice>,
    /// Smallest target diameter in px (default 2.5; 1 to 1000).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "openapi", schema(minimum = 1.0, maximum = 1000.0))]
    pub min_diameter_px: Option<f64>,
    /// Largest target diameter in px (default 64; 1 to 1000, above the smallest).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "openapi", schema(minimum = 1.0, maximum = 1000.0))]
    pub max_diameter_px: Option<f64>,
}

/// The settings a detection ran with and where each came from, as an epoch's report keeps them.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct DetectionUsed {
    /// The polarity asked for: `auto`, `bright` or `dark`.
    pub polarity: PolarityChoice,
    /// The polarity the image's targets had: `bright` or `dark`.
    pub found: String,
    /// Smallest target diameter in px.
    pub min_diameter_px: f64,
    /// Largest target diameter in px.
    pub max_diameter_px: f64,
    /// Where the settings came from: `epoch.json`, `site` and / or `default`, in that order of
    /// precedence.
    pub from: Vec<String>,
}

impl DetectionSettings {
    /// These settings, each field not given taken from `base`.
    pub fn over(self, base: DetectionSettings) -> DetectionSettings {
        DetectionSettings {
            polarity: self.polarity.or(base.polarity),
            min_diameter_px: self.min_diameter_px.or(base.min_diameter_px),
            max_diameter_px: self.max_diameter_px.or(base.max_diameter_px),
        }
    }

    /// Checks the fields, alone and with `base` (the settings these override, `None`: the
    /// defaults); the message names the field at fault, e.g. `detection.min_diameter_px`.
    pub fn validate(&self, base: Option<&DetectionSettings>) -> Result<(), String> {
        for (name, v) in [
            ("min_diameter_px", self.min_diameter_px),
            ("max_diameter_px", self.max_diameter_px),
        ] {
            if let Some(d) = v {
                if !(MIN_DIAMETER_PX..=MAX_DIAMETER_PX).contains(&d) {
                    return Err(format!(
                        "detection.{name} {d}: a diameter from {MIN_DIAMETER_PX} to {MAX_DIAMETER_PX} px"
                    ));
                }
            }
        }
        let merged = self.over(base.copied().unwrap_or_default());
        let o = merged.options();
        if o.min_diameter_px >= o.max_diameter_px {
            return Err(format!(
                "detection.min_diameter_px {} must be smaller than detection.max_diameter_px {}",
                o.min_diameter_px, o.max_diameter_px
            ));
        }
        Ok(())
    }

    /// The detector's options with these settings, the rest default.
    pub fn options(&self) -> DetectOptions {
        let mut o = DetectOptions::default();
        self.apply(&mut o);
        o
    }

    /// Sets the fields given in `opts`. The background grid's cell grows to twice the largest
    /// diameter where the default cell is smaller.
    pub fn apply(&self, opts: &mut DetectOptions) {
        if let Some(p) = self.polarity {
            opts.polarity = p.polarity();
        }
        if let Some(d) = self.min_diameter_px {
            opts.min_diameter_px = d;
        }
        if let Some(d) = self.max_diameter_px {
            opts.max_diameter_px = d;
            opts.background_cell_px = opts.background_cell_px.max((2.0 * d).ceil() as usize);
        }
    }

    /// What a detection with `opts` (these settings applied) that found `found` used, with the
    /// sources of the settings.
    pub fn used(opts: &DetectOptions, found: Polarity, from: Vec<String>) -> DetectionUsed {
        DetectionUsed {
            polarity: PolarityChoice::of(opts.polarity),
            found: found.name().to_string(),
            min_diameter_px: opts.min_diameter_px,
            max_diameter_px: opts.max_diameter_px,
            from,
        }
    }

    /// Whether no field is given.
    pub fn is_empty(&self) -> bool {
        *self == DetectionSettings::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_folders_fields_override_the_sites_and_the_rest_stays_default() {
        let site = DetectionSettings {
            polarity: Some(PolarityChoice::Dark),
            min_diameter_px: Some(10.0),
            max_diameter_px: None,
        };
        let folder = DetectionSettings {
            min_diameter_px: Some(4.0),
            ..DetectionSettings::default()
        };
        let o = folder.over(site).options();
        assert_eq!(o.polarity, Some(Polarity::DarkOnBright));
        assert_eq!(o.min_diameter_px, 4.0);
        assert_eq!(o.max_diameter_px, DetectOptions::default().max_diameter_px);
        let big = DetectionSettings {
            max_diameter_px: Some(200.0),
            ..DetectionSettings::default()
        };
        assert_eq!(big.options().background_cell_px, 400);
    }

    #[test]
    fn a_bad_range_names_its_field() {
        let low = DetectionSettings {
            min_diameter_px: Some(0.5),
            ..DetectionSettings::default()
        };
        assert!(low
            .validate(None)
            .unwrap_err()
            .contains("detection.min_diameter_px"));
        let crossed = DetectionSettings {
            min_diameter_px: Some(80.0),
            ..DetectionSettings::default()
        };
        let e = crossed.validate(None).unwrap_err();
        assert!(e.contains("detection.max_diameter_px 64"), "{e}");
        let site = DetectionSettings {
            max_diameter_px: Some(100.0),
            ..DetectionSettings::default()
        };
        assert!(crossed.validate(Some(&site)).is_ok());
    }
}
