//! What an extraction returns: [`PlaneSegmentation`] (the label image and the planes) and
//! [`PlaneInfo`] (one plane's fit, size, residuals and uncertainty).

use super::*;

/// One extracted plane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlaneInfo {
    /// Label in the label image (1-based; planes are sorted by decreasing size).
    pub id: u16,
    /// The 3D plane in camera coordinates: the fit of the pixels within `τ` of it (for a
    /// surface whose bent pieces were joined, see [`PlaneConfig::bend_px_per_px2`], of its
    /// largest piece).
    pub plane: Plane,
    /// The disparity function `D = a·x + b·y + c` of the plane.
    pub affine: DisparityAffine,
    /// Number of pixels with this label (the joined pieces' included).
    pub pixels: usize,
    /// RMS disparity residual of the pixels the plane was fitted on, pixels.
    pub rms_px: f64,
    /// RMS point-to-plane distance of the pixels the plane was fitted on, metres.
    pub rms_m: f64,
    /// Centroid of the points the plane was fitted on, camera coordinates, metres.
    pub centroid_m: Point3<f64>,
    /// Standard uncertainty of the normal from the noise model: the RMS angle between the
    /// fitted normal and the true one, degrees (infinite when the pixels do not determine the
    /// plane, which includes an uncertainty of 61.2° or more: the RMS angle of a normal guessed
    /// uniformly on the hemisphere facing the camera). The disparity error of the camera's
    /// sensor model (`σ_D`, the `1/q` quantisation), correlated over the block-matching window
    /// ([`PlaneConfig::noise_window_x_px`]), or the fit's own residual where that is larger,
    /// propagated through the least-squares fit (the `uncertainty` module). Small, far or
    /// narrow planes are the uncertain ones; on the real sequences it predicts which planes
    /// are found again in later frames (docs/bench/README.md, session 36).
    pub normal_sigma_deg: f64,
    /// Standard uncertainty of the plane's position along its normal at
    /// [`PlaneInfo::centroid_m`], metres (uncorrelated with the normal's there; infinite when
    /// undetermined).
    pub offset_sigma_m: f64,
}

/// The result of a plane extraction.
#[derive(Debug, Clone, PartialEq)]
pub struct PlaneSegmentation {
    /// Per-pixel plane id (0 = not on any plane).
    pub labels: Image<u16>,
    /// The planes, `planes[i].id == i + 1`.
    pub planes: Vec<PlaneInfo>,
}
