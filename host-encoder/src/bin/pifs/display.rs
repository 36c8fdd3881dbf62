//! `pifs decode --display PANEL`: the picture as a small display of fewer levels shows it:
//! each decoded pixel converted by decoder-core's embedded-graphics colours at its position, as
//! the device's `graphics::DrawSink` converts it (dithering included), then written back as an
//! 8-bit image.

use decoder_core::graphics::{Dither, FromGray, Threshold};
use embedded_graphics_core::pixelcolor::{
    BinaryColor, Gray2, Gray4, Gray8, GrayColor, Rgb565, Rgb666, Rgb888, RgbColor,
};

/// What `--display` asks for: the panel, and how its levels are reached.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Showing {
    /// The panel.
    pub panel: Panel,
    /// How the panel's levels are reached.
    pub dither: Dither,
}

/// A kind of panel `pifs decode --display` shows the picture on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Panel {
    /// 16-bit colour (ST7789, ILI9341, SSD1351, ...).
    Rgb565,
    /// 18-bit colour (ILI9488, ...).
    Rgb666,
    /// 16 greys (SSD1322, SSD1327 OLEDs).
    Gray4,
    /// 4 greys (grey e-paper).
    Gray2,
    /// Black and white (SSD1306, SH1106 OLEDs, memory LCDs, e-paper).
    Mono,
}

/// The panels by name, for `--display`.
const PANELS: [(&str, Panel); 5] = [
    ("rgb565", Panel::Rgb565),
    ("rgb666", Panel::Rgb666),
    ("gray4", Panel::Gray4),
    ("gray2", Panel::Gray2),
    ("mono", Panel::Mono),
];

/// A panel's name, as `--display` takes it.
pub fn panel_name(panel: Panel) -> &'static str {
    PANELS
        .iter()
        .find(|&&(_, p)| p == panel)
        .map_or("", |&(name, _)| name)
}

/// Parses a `--display` value.
pub fn parse_panel(text: &str) -> Result<Panel, String> {
    PANELS
        .iter()
        .find(|(name, _)| name.eq_ignore_ascii_case(text))
        .map(|&(_, panel)| panel)
        .ok_or_else(|| {
            let names: Vec<&str> = PANELS.iter().map(|(name, _)| *name).collect();
            format!("not a panel: {text} (one of {})", names.join(", "))
        })
}

/// Parses a `--dither` value: `ordered` or `nearest`.
pub fn parse_dither(text: &str) -> Result<Dither, String> {
    match text.to_ascii_lowercase().as_str() {
        "ordered" => Ok(Dither::Ordered),
        "nearest" => Ok(Dither::Nearest),
        _ => Err(format!("not a dithering: {text} (ordered or nearest)")),
    }
}

/// A picture of `width x height` pixels of `channels` 8-bit samples, row-major: a decode, or
/// what a panel shows of it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Picture {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// 1 (grey) or 3 (RGB).
    pub channels: u8,
    /// The samples.
    pub pixels: Vec<u8>,
}

/// A decoded `picture` as the panel of `showing` shows it: each pixel converted as the
/// device's `graphics::DrawSink` converts it at that image position.
pub fn show_picture(picture: &Picture, showing: Showing) -> Picture {
    let Showing { panel, dither } = showing;
    match panel {
        Panel::Rgb565 => convert::<Rgb565>(picture, dither),
        Panel::Rgb666 => convert::<Rgb666>(picture, dither),
        Panel::Gray4 => convert::<Gray4>(picture, dither),
        Panel::Gray2 => convert::<Gray2>(picture, dither),
        Panel::Mono => convert::<BinaryColor>(picture, dither),
    }
}

fn convert<C: Shade>(picture: &Picture, dither: Dither) -> Picture {
    let (width, height) = (picture.width, picture.height);
    let n = usize::from(C::CHANNELS);
    let mut out = vec![0; width as usize * height as usize * n];
    let step = usize::from(picture.channels.max(1));
    let positions = (0..height).flat_map(|y| (0..width).map(move |x| (x, y)));
    for ((p, (x, y)), slot) in picture
        .pixels
        .chunks_exact(step)
        .zip(positions)
        .zip(out.chunks_exact_mut(n))
    {
        let threshold = match dither {
            Dither::Ordered => Threshold::ordered(x, y),
            Dither::Nearest => Threshold::NEAREST,
        };
        let colour = match *p {
            [r, g, b] => C::from_rgb_with(r, g, b, threshold),
            _ => C::from_gray_with(p[0], threshold),
        };
        colour.put(slot);
    }
    Picture {
        width,
        height,
        channels: C::CHANNELS,
        pixels: out,
    }
}

/// A panel colour written back as 8-bit samples.
trait Shade: FromGray {
    /// Samples a pixel.
    const CHANNELS: u8;
    /// The colour's samples, into `out[..CHANNELS]`.
    fn put(self, out: &mut [u8]);
}

impl Shade for Rgb565 {
    const CHANNELS: u8 = 3;
    fn put(self, out: &mut [u8]) {
        let c = Rgb888::from(self);
        out.copy_from_slice(&[c.r(), c.g(), c.b()]);
    }
}

impl Shade for Rgb666 {
    const CHANNELS: u8 = 3;
    fn put(self, out: &mut [u8]) {
        let c = Rgb888::from(self);
        out.copy_from_slice(&[c.r(), c.g(), c.b()]);
    }
}

impl Shade for Gray4 {
    const CHANNELS: u8 = 1;
    fn put(self, out: &mut [u8]) {
        out[0] = Gray8::from(self).luma();
    }
}

impl Shade for Gray2 {
    const CHANNELS: u8 = 1;
    fn put(self, out: &mut [u8]) {
        out[0] = Gray8::from(self).luma();
    }
}

impl Shade for BinaryColor {
    const CHANNELS: u8 = 1;
    fn put(self, out: &mut [u8]) {
        out[0] = if self.is_on() { 255 } else { 0 };
    }
}
