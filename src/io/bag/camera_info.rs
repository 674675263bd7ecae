//! A `sensor_msgs/CameraInfo` as a [`Camera`] of the kinds Kalibr calibrates: pinhole
//! intrinsics with radial-tangential (`radtan`) or equidistant distortion.
//!
//! - `plumb_bob`: `D = [k1, k2, p1, p2, k3]` (four coefficients also read). Kalibr's radtan
//!   has no `k3`, so a nonzero `k3` is an error.
//! - `rational_polynomial`: `D = [k1, k2, p1, p2, k3, k4, k5, k6, ...]`; read as radtan when
//!   every coefficient after `p2` is zero, an error otherwise.
//! - `equidistant` (also spelled `fisheye`): `D = [k1, k2, k3, k4]`, Kalibr's equidistant.
//!
//! `K` (row-major) must be `[fx 0 cx; 0 fy cy; 0 0 1]` with positive focal lengths; an
//! all-zero `K` is how drivers say the camera is not calibrated, and is an error. Binning and
//! a region of interest would make the model describe images other than the ones published,
//! so they are errors too.

use super::cdr::{self, CameraInfo};
use super::open::OpenBag;
use crate::error::{Error, Result};
use crate::types::camera::{Camera, Distortion};

impl CameraInfo {
    /// The camera of this message (see the module documentation for what is accepted); an
    /// error says why a message does not give one.
    pub fn model(&self) -> Result<Camera> {
        let k = &self.k;
        if k.iter().all(|&v| v == 0.0) {
            return Err(Error::Input(format!(
                "CameraInfo of frame {:?}: K is all zeros: the camera is not calibrated (calibrate \
                 the cameras with Kalibr instead)",
                self.header.frame_id
            )));
        }
        let [fx, skew, cx, k10, fy, cy, k20, k21, k22] = *k;
        let finite_positive = k.iter().all(|v| v.is_finite()) && fx > 0.0 && fy > 0.0;
        if !finite_positive || k10 != 0.0 || k20 != 0.0 || k21 != 0.0 || k22 != 1.0 {
            return Err(Error::Input(format!(
                "CameraInfo of frame {:?}: K = {k:?} is not an intrinsic matrix \
                 [fx 0 cx; 0 fy cy; 0 0 1] with positive focal lengths",
                self.header.frame_id
            )));
        }
        if skew.abs() > 1e-9 * fx {
            return Err(Error::Input(format!(
                "CameraInfo of frame {:?}: K has a skew of {skew}, which Kalibr's pinhole model \
                 does not have",
                self.header.frame_id
            )));
        }
        if self.binning_x > 1 || self.binning_y > 1 {
            return Err(Error::Input(format!(
                "CameraInfo of frame {:?}: binning {}x{} is not supported (the model would be of \
                 the full-resolution image)",
                self.header.frame_id, self.binning_x, self.binning_y
            )));
        }
        let roi = &self.roi;
        let whole = roi.x_offset == 0
            && roi.y_offset == 0
            && (roi.width == 0 || roi.width == self.width)
            && (roi.height == 0 || roi.height == self.height);
        if !whole {
            return Err(Error::Input(format!(
                "CameraInfo of frame {:?}: a region of interest ({}x{} at {},{}) is not supported \
                 (the model would be of the full image)",
                self.header.frame_id, roi.width, roi.height, roi.x_offset, roi.y_offset
            )));
        }
        let distortion = self.distortion()?;
        Ok(Camera {
            fu: fx,
            fv: fy,
            pu: cx,
            pv: cy,
            distortion,
            width: self.width,
            height: self.height,
        })
    }

    /// The distortion model from `distortion_model` and `D`.
    fn distortion(&self) -> Result<Distortion> {
        let d = &self.d;
        let name = self.distortion_model.as_str();
        let err = |msg: String| {
            Err(Error::Input(format!(
                "CameraInfo of frame {:?}: distortion_model {name:?} with D = {d:?}: {msg}",
                self.header.frame_id
            )))
        };
        if !d.iter().all(|v| v.is_finite()) {
            return err("a coefficient is not a finite number".into());
        }
        let four =
            |d: &[f64]| -> [f64; 4] { std::array::from_fn(|i| d.get(i).copied().unwrap_or(0.0)) };
        match name {
            "plumb_bob" => {
                if !(d.len() == 4 || d.len() == 5) {
                    return err(format!(
                        "plumb_bob has 5 coefficients (k1 k2 p1 p2 k3), not {}",
                        d.len()
                    ));
                }
                if d.get(4).is_some_and(|&k3| k3 != 0.0) {
                    return err(
                        "k3 is not zero, and Kalibr's radtan has 4 coefficients (k1 k2 p1 p2): \
                         calibrate the cameras with Kalibr instead"
                            .into(),
                    );
                }
                let [k1, k2, p1, p2] = four(d);
                Ok(Distortion::RadTan { k1, k2, p1, p2 })
            }
            "rational_polynomial" => {
                if d.len() < 4 {
                    return err(format!(
                        "rational_polynomial needs at least k1 k2 p1 p2, and D has {} \
                         coefficients",
                        d.len()
                    ));
                }
                if d.iter().skip(4).any(|&c| c != 0.0) {
                    return err(
                        "a coefficient after k1 k2 p1 p2 is not zero, and Kalibr's radtan has \
                         only those 4: calibrate the cameras with Kalibr instead"
                            .into(),
                    );
                }
                let [k1, k2, p1, p2] = four(d);
                Ok(Distortion::RadTan { k1, k2, p1, p2 })
            }
            "equidistant" | "fisheye" => {
                if d.len() != 4 {
                    return err(format!(
                        "the equidistant model has 4 coefficients (k1 k2 k3 k4), not {}",
                        d.len()
                    ));
                }
                let [k1, k2, k3, k4] = four(d);
                Ok(Distortion::Equidistant { k1, k2, k3, k4 })
            }
            _ => err(
                "not a supported distortion model (plumb_bob, rational_polynomial, equidistant \
                 or fisheye)"
                    .into(),
            ),
        }
    }
}

/// The camera of a bag's `CameraInfo` topic (its first message that describes a calibrated
/// camera), for a bag of one camera and no camchain. `None` when the image topic has no
/// `CameraInfo`.
pub fn camera_from_info(ob: &OpenBag, cam: usize) -> Result<Option<Camera>> {
    let Some(Some(info)) = ob.roles.camera_info.get(cam).copied() else {
        return Ok(None);
    };
    let topic = ob.topic(info).clone();
    let mut found: Option<Result<Camera>> = None;
    ob.bag.messages(&|i| i == info, &mut |m| {
        if matches!(found, Some(Ok(_))) {
            return Ok(());
        }
        let r = cdr::decode::<cdr::CameraInfo>(m.data, topic.serialization)
            .and_then(|ci| ci.model())
            .map_err(|e| Error::Input(format!("{} message {}: {e}", topic.name, m.index)));
        found = Some(r);
        Ok(())
    })?;
    match found {
        None => Ok(None),
        Some(r) => r.map(Some),
    }
}

#[cfg(test)]
mod tests {
    use super::super::cdr::Header;
    use super::*;

    fn info(model: &str, d: &[f64]) -> CameraInfo {
        CameraInfo {
            header: Header::default(),
            height: 480,
            width: 640,
            distortion_model: model.into(),
            d: d.to_vec(),
            k: [500.0, 0.0, 320.0, 0.0, 501.0, 240.0, 0.0, 0.0, 1.0],
            r: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            p: [0.0; 12],
            binning_x: 0,
            binning_y: 0,
            roi: Default::default(),
        }
    }

    #[test]
    fn models() {
        let m = info("plumb_bob", &[-0.25, 0.1, 0.001, -0.002, 0.0])
            .model()
            .unwrap();
        assert_eq!((m.fu, m.fv, m.pu, m.pv), (500.0, 501.0, 320.0, 240.0));
        assert_eq!(m.distortion.coeffs(), [-0.25, 0.1, 0.001, -0.002]);
        assert_eq!(m.distortion.kalibr_name(), "radtan");
        let m = info(
            "rational_polynomial",
            &[0.1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        )
        .model()
        .unwrap();
        assert_eq!(m.distortion.coeffs(), [0.1, 0.0, 0.0, 0.0]);
        let m = info("fisheye", &[0.1, 0.2, 0.3, 0.4]).model().unwrap();
        assert_eq!(
            m.distortion,
            Distortion::Equidistant {
                k1: 0.1,
                k2: 0.2,
                k3: 0.3,
                k4: 0.4
            }
        );
        // All-zero coefficients: the images are already undistorted, a radtan lens without
        // distortion.
        let m = info("plumb_bob", &[0.0; 5]).model().unwrap();
        assert_eq!(m.distortion.coeffs(), [0.0; 4]);
    }

    #[test]
    fn refusals() {
        let e = |c: CameraInfo| c.model().unwrap_err().to_string();
        let s = e(info("plumb_bob", &[0.1, 0.0, 0.0, 0.0, 0.01]));
        assert!(
            s.contains("4 coefficients") && s.contains("calibrate"),
            "{s}"
        );
        let s = e(info(
            "rational_polynomial",
            &[0.1, 0.0, 0.0, 0.0, 0.0, 0.2, 0.0, 0.0],
        ));
        assert!(s.contains("not zero"), "{s}");
        let s = e(info("kannala_brandt", &[0.0; 4]));
        assert!(s.contains("\"kannala_brandt\""), "{s}");
        let mut c = info("plumb_bob", &[0.0; 5]);
        c.k = [0.0; 9];
        assert!(e(c).contains("not calibrated"));
        let mut c = info("plumb_bob", &[0.0; 5]);
        c.k[1] = 2.0;
        assert!(e(c).contains("skew"));
        let mut c = info("plumb_bob", &[0.0; 5]);
        c.binning_x = 2;
        assert!(e(c).contains("binning"));
        let mut c = info("plumb_bob", &[0.0; 5]);
        c.roi.width = 100;
        assert!(e(c).contains("region of interest"));
        assert!(e(info("equidistant", &[0.0; 5])).contains("4 coefficients"));
        assert!(e(info("plumb_bob", &[f64::NAN; 5])).contains("finite"));
    }
}
