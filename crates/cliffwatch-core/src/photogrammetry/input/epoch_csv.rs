//! The CSV form of an upload (`image,point,x_mm,y_mm` a line): turned into the JSON upload
//! form ([`EpochInput`]) with the camera of its images ([`csv_camera`]).

use std::collections::HashMap;

use thiserror::Error;

use super::epoch::{CameraInput, MAX_IMAGES};
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
    /// The camera of the CSV's images is not clear: the site has several and none was named,
    /// or the one named is not among them.
    #[error("{0}")]
    Camera(String),
}

/// The camera of a CSV upload's images: the one named (`?camera=`), else the site's only
/// camera. Several cameras and none named is [`CsvError::Camera`]: taking one of them would
/// give the images another camera's principal distance and pixel size without a word.
pub fn csv_camera(
    mut cameras: Vec<CameraInput>,
    named: Option<&str>,
) -> Result<CameraInput, CsvError> {
    let ids = || {
        cameras
            .iter()
            .map(|c| c.id.as_str())
            .collect::<Vec<_>>()
            .join(", ")
    };
    match named {
        _ if cameras.is_empty() => Err(CsvError::NoCameras),
        Some(id) => match cameras.iter().position(|c| c.id == id) {
            Some(k) => Ok(cameras.swap_remove(k)),
            None => Err(CsvError::Camera(format!(
                "camera '{}': the site's cameras are {}",
                crate::contract::truncate_for_message(id),
                ids()
            ))),
        },
        None if cameras.len() == 1 => Ok(cameras.remove(0)),
        None => Err(CsvError::Camera(format!(
            "the site has {} cameras ({}): name the images' camera with ?camera=",
            cameras.len(),
            ids()
        ))),
    }
}

/// The 1-based line of `text` where the record read from byte `offset` on starts. The `csv`
/// crate's position is where it began reading, before the comment lines (`#`) and empty lines
/// it skipped, and its line count leaves comment lines out; both are stepped over here.
fn line_at(text: &str, offset: u64) -> usize {
    let bytes = text.as_bytes();
    let mut at = usize::try_from(offset).map_or(bytes.len(), |o| o.min(bytes.len()));
    loop {
        match bytes[at..] {
            [b'#', ..] => {
                at = bytes[at..]
                    .iter()
                    .position(|&b| b == b'\n')
                    .map_or(bytes.len(), |k| at + k + 1);
            }
            [b'\r', b'\n', ..] => at += 2,
            [b'\n' | b'\r', ..] => at += 1,
            _ => break,
        }
    }
    1 + bytes[..at].iter().filter(|&&b| b == b'\n').count()
}

/// Builds an upload from the CSV form (`image,point,x_mm,y_mm` a line, optional header), the
/// observation time and the camera of every image (see [`csv_camera`]).
pub fn epoch_from_csv(
    text: &str,
    observed_at: &str,
    camera: CameraInput,
) -> Result<EpochInput, CsvError> {
    use super::epoch::{ImageInput, ObservationInput};
    let camera_id = camera.id.clone();
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        // Each line's field count is checked below, with the line's number and a 422.
        .flexible(true)
        .trim(csv::Trim::All)
        .comment(Some(b'#'))
        .from_reader(text.as_bytes());
    let mut images: Vec<ImageInput> = Vec::new();
    let mut index: HashMap<String, usize> = HashMap::new();
    for (i, record) in reader.records().enumerate() {
        // The line in the file, counting comments, blank lines and quoted line breaks: the one an
        // editor shows.
        let record = record.map_err(|e| CsvError::Malformed {
            line: e.position().map_or(i + 1, |p| line_at(text, p.byte())),
            reason: e.to_string(),
        })?;
        let line = record.position().map_or(i + 1, |p| line_at(text, p.byte()));
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
                        crate::contract::truncate_for_message(&got.join(","))
                    ),
                });
            }
            continue;
        }
        let number = |k: usize| -> Result<f64, CsvError> {
            record[k].parse().map_err(|_| CsvError::InvalidLine {
                line,
                reason: format!(
                    "'{}' is not a number",
                    crate::contract::truncate_for_message(&record[k])
                ),
            })
        };
        let obs = ObservationInput {
            point: record[1].to_string(),
            x_mm: Some(number(2)?),
            y_mm: Some(number(3)?),
            col: None,
            row: None,
            sigma_mm: None,
        };
        match index.get(&record[0]) {
            Some(&k) => images[k].observations.push(obs),
            None if images.len() == MAX_IMAGES => {
                return Err(CsvError::InvalidLine {
                    line,
                    reason: format!(
                        "image '{}': an epoch holds at most {MAX_IMAGES} images",
                        crate::contract::truncate_for_message(&record[0])
                    ),
                });
            }
            None => {
                index.insert(record[0].to_string(), images.len());
                images.push(ImageInput {
                    id: record[0].to_string(),
                    camera: camera_id.clone(),
                    station: None,
                    observations: vec![obs],
                });
            }
        }
    }
    Ok(EpochInput {
        observed_at: observed_at.to_string(),
        label: None,
        cameras: vec![camera],
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
            cam.clone(),
        )
        .unwrap();
        assert_eq!(e.images.len(), 2);
        assert_eq!(e.images[0].observations.len(), 2);
        assert!(epoch_from_csv("A,1,x,2", "2026-01-01T00:00:00Z", cam.clone()).is_err());
        // without a header the columns are image,point,x_mm,y_mm
        let e = epoch_from_csv("A,1,0.5,0.25\n", "2026-01-01T00:00:00Z", cam.clone()).unwrap();
        assert_eq!(e.images[0].observations[0].x_mm, Some(0.5));
    }

    #[test]
    fn the_camera_is_the_one_named_or_the_only_one() {
        let cam = |id: &str| -> CameraInput {
            serde_json::from_str(&format!(r#"{{"id": "{id}", "c_mm": 300.0}}"#)).unwrap()
        };
        assert!(matches!(csv_camera(vec![], None), Err(CsvError::NoCameras)));
        assert_eq!(csv_camera(vec![cam("b")], None).unwrap().id, "b");
        let two = || vec![cam("b"), cam("a")];
        // Several and none named: refused, naming them (not the first by name, as before).
        match csv_camera(two(), None) {
            Err(CsvError::Camera(m)) => {
                assert!(m.contains("b, a") && m.contains("?camera="), "{m}")
            }
            other => panic!("{other:?}"),
        }
        assert_eq!(csv_camera(two(), Some("b")).unwrap().id, "b");
        assert_eq!(csv_camera(two(), Some("a")).unwrap().id, "a");
        match csv_camera(two(), Some("c")) {
            Err(CsvError::Camera(m)) => assert!(m.contains("camera 'c'"), "{m}"),
            other => panic!("{other:?}"),
        }
        let e = epoch_from_csv("A,1,0.5,0.25\n", "2026-01-01T00:00:00Z", cam("a")).unwrap();
        assert_eq!(e.cameras.len(), 1);
        assert_eq!(e.images[0].camera, "a");
    }

    #[test]
    fn more_images_than_an_epoch_holds_are_refused_at_the_line() {
        let cam: CameraInput = serde_json::from_str(r#"{"id": "cam", "c_mm": 300.0}"#).unwrap();
        let text: String = (0..=MAX_IMAGES)
            .map(|k| format!("I{k},1,0.5,0.25\n"))
            .collect();
        match epoch_from_csv(&text, "2026-01-01T00:00:00Z", cam.clone()) {
            Err(CsvError::InvalidLine { line, reason }) => {
                assert_eq!(line, MAX_IMAGES + 1);
                assert!(reason.contains("I200"), "{reason}");
            }
            other => panic!("{other:?}"),
        }
        let text: String = (0..MAX_IMAGES)
            .map(|k| format!("I{k},1,0.5,0.25\n"))
            .collect();
        let e = epoch_from_csv(&text, "2026-01-01T00:00:00Z", cam).unwrap();
        assert_eq!(e.images.len(), MAX_IMAGES);
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
            match epoch_from_csv(&text, "2026-01-01T00:00:00Z", cam.clone()) {
                Err(CsvError::InvalidLine { line: 1, reason }) => {
                    assert!(reason.contains(header), "{reason}")
                }
                other => panic!("{header}: {other:?}"),
            }
        }
    }

    /// An error names the line of the file, comments and blank lines included.
    #[test]
    fn an_error_names_the_line_of_the_file() {
        let cam: CameraInput = serde_json::from_str(r#"{"id": "cam", "c_mm": 300.0}"#).unwrap();
        let text = "# campaign 12\nimage,point,x_mm,y_mm\n\nA,1,0.5,0.25\n# B follows\nB,1,0.5,x\n";
        match epoch_from_csv(text, "2026-01-01T00:00:00Z", cam.clone()) {
            Err(CsvError::InvalidLine { line, reason }) => {
                assert_eq!(line, 6, "{reason}");
                assert!(reason.contains("'x'"), "{reason}");
            }
            other => panic!("{other:?}"),
        }
        let text = "# header next\nimage,point,x_mm,y_mm\n\nA,1,0.5\n";
        match epoch_from_csv(text, "2026-01-01T00:00:00Z", cam) {
            Err(CsvError::InvalidLine { line, .. }) => assert_eq!(line, 4),
            other => panic!("{other:?}"),
        }
    }
}
