//! Borrowed depth maps: [`DepthView`], a row-major `f32` slice in metres with its size, so a
//! caller that already holds the pixels (a NumPy array, a ROS message buffer) can run the
//! algorithms without copying them into a [`DepthImage`].

use crate::error::{CoreError, Result};
use crate::image::DepthImage;

/// A borrowed depth map: `f32` metres along the optical axis, row-major, 0 = invalid.
///
/// Every algorithm entry point that reads a depth map takes `impl Into<DepthView>`, so both
/// `&DepthImage` and a view over someone else's buffer work.
///
/// ```
/// use sl_core::DepthView;
///
/// let pixels = vec![1.5_f32; 4 * 3];
/// let view = DepthView::new(4, 3, &pixels)?;
/// assert_eq!((view.width(), view.height()), (4, 3));
/// assert!(DepthView::new(4, 4, &pixels).is_err());
/// # Ok::<(), sl_core::CoreError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DepthView<'a> {
    width: usize,
    height: usize,
    data: &'a [f32],
}

impl<'a> DepthView<'a> {
    /// Wraps `data` (row-major, `width * height` values in metres).
    pub fn new(width: usize, height: usize, data: &'a [f32]) -> Result<Self> {
        match width.checked_mul(height) {
            Some(n) if n == data.len() => Ok(Self {
                width,
                height,
                data,
            }),
            _ => Err(CoreError::BufferLength {
                len: data.len(),
                width,
                height,
            }),
        }
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// The row-major values.
    pub fn data(&self) -> &'a [f32] {
        self.data
    }

    /// Copies into an owned [`DepthImage`].
    pub fn to_image(&self) -> DepthImage {
        // The size was checked when the view was made.
        DepthImage::from_image(crate::Image::from_fn(self.width, self.height, |x, y| {
            self.data[y * self.width + x]
        }))
    }
}

impl<'a> From<&'a DepthImage> for DepthView<'a> {
    fn from(image: &'a DepthImage) -> Self {
        Self {
            width: image.width(),
            height: image.height(),
            data: image.data(),
        }
    }
}

impl DepthImage {
    /// A borrowed view of this image.
    pub fn view(&self) -> DepthView<'_> {
        self.into()
    }
}
