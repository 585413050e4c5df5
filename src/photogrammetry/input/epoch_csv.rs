//! The CSV form of an upload (`image,point,x_mm,y_mm` a line): turned into the JSON upload
//! form ([`EpochInput`]) with the site's cameras.

use thiserror::Error;

use super::epoch::CameraInput;
use crate::photogrammetry::EpochInput;

/// Why a CSV upload cannot be read.
#[derive(Debug, Error)]
pub enum CsvError {
    /// Not CSV at all (the reader failed).
    #[error("CSV line {line}: {reason}")]
    Malformed {
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        reason: String,
    },
    /// CSV, but a line is not `image,point,x_mm,y_mm` (field count, a coordinate not a number).
    #[error("CSV line {line}: {reason}")]
    InvalidLine {
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        reason: String,
    },
    /// The site has no cameras yet (upload one JSON epoch first).
    #[error("the site has no cameras yet: upload a JSON epoch first")]
    NoCameras,
}

/// Builds an upload from the CSV form (`image,point,x_mm,y_mm` a line, optional header), the
/// observation time and the site's cameras (every image uses the first camera).
pub fn epoch_from_csv(
    text: &str,
    observed_at: &str,
    cameras: Vec<CameraInput>,
) -> Result<EpochInput, CsvError> {
    use super::epoch::{ImageInput, ObservationInput};
    let camera = cameras.first().ok_or(CsvError::NoCameras)?.id.clone();
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        // Each line's field count is checked below, with the line's number and a 422.
        .flexible(true)
        .trim(csv::Trim::All)
        .comment(Some(b'#'))
        .from_reader(text.as_bytes());
    let mut images: Vec<ImageInput> = Vec::new();
    for (i, record) in reader.records().enumerate() {
        let line = i + 1;
        let record = record.map_err(|e| CsvError::Malformed {
            line,
            reason: e.to_string(),
        })?;
        if record.len() != 4 {
            return Err(CsvError::InvalidLine {
                line,
                reason: format!("{} fields, want image,point,x_mm,y_mm", record.len()),
            });
        }
        if i == 0 && &record[0] == "image" {
            // a header is read, not assumed: swapped or pixel columns would be misread as mm
            let got: Vec<&str> = record.iter().collect();
            if got != ["image", "point", "x_mm", "y_mm"] {
                return Err(CsvError::InvalidLine {
                    line,
                    reason: format!(
                        "header '{}': the columns must be image,point,x_mm,y_mm in this order",
                        got.join(",")
                    ),
                });
            }
            continue;
        }
        let number = |k: usize| -> Result<f64, CsvError> {
            record[k].parse().map_err(|_| CsvError::InvalidLine {
                line,
                reason: format!("'{}' is not a number", &record[k]),
            })
        };
        let obs = ObservationInput {
            point: record[1].to_string(),
            x_mm: Some(number(2)?),
            y_mm: Some(number(3)?),
            col: None,
            row: None,
        };
        match images.iter_mut().find(|im| im.id == record[0]) {
            Some(im) => im.observations.push(obs),
            None => images.push(ImageInput {
                id: record[0].to_string(),
                camera: camera.clone(),
                station: None,
                observations: vec![obs],
            }),
        }
    }
    Ok(EpochInput {
        observed_at: observed_at.to_string(),
        label: None,
        cameras,
        images,
        control: Vec::new(),
        approx: Vec::new(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_groups_observations_by_image() {
        let cam: CameraInput = serde_json::from_str(r#"{"id": "cam", "c_mm": 300.0}"#).unwrap();
        let e = epoch_from_csv(
            "image,point,x_mm,y_mm\nA,1,0.5,0.25\nA,2,1,2\nB,1,3,4\n",
            "2026-01-01T00:00:00Z",
            vec![cam.clone()],
        )
        .unwrap();
        assert_eq!(e.images.len(), 2);
        assert_eq!(e.images[0].observations.len(), 2);
        assert!(epoch_from_csv("A,1,x,2", "2026-01-01T00:00:00Z", vec![]).is_err());
        // without a header the columns are image,point,x_mm,y_mm
        let e =
            epoch_from_csv("A,1,0.5,0.25\n", "2026-01-01T00:00:00Z", vec![cam.clone()]).unwrap();
        assert_eq!(e.images[0].observations[0].x_mm, Some(0.5));
    }

    #[test]
    fn a_header_other_than_the_contracts_is_refused_not_misread() {
        let cam: CameraInput = serde_json::from_str(r#"{"id": "cam", "c_mm": 300.0}"#).unwrap();
        for header in [
            "image,point,y_mm,x_mm",
            "image,point,col,row",
            "image,point,xmm,ymm",
        ] {
            let text = format!("{header}\nA,1,0.5,0.25\n");
            match epoch_from_csv(&text, "2026-01-01T00:00:00Z", vec![cam.clone()]) {
                Err(CsvError::InvalidLine { line: 1, reason }) => {
                    assert!(reason.contains(header), "{reason}")
                }
                other => panic!("{header}: {other:?}"),
            }
        }
    }
}
