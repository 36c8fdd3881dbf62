//! `io::Loaded::analyse`, the library's one entry for any image: a grayscale image makes
//! grayscale streams, a colour image colour streams, a 16-bit surface 16-bit streams with its
//! range, each the same stream as the specific analysis makes.

use decoder_core::Decoder;
use host_encoder::io::{Loaded, Surface};
use host_encoder::{analyse, analyse_colour, EncoderConfig, Plane, Target};

const W: u32 = 48;
const H: u32 = 40;

fn rgb() -> Vec<u8> {
    (0..H)
        .flat_map(|y| {
            (0..W).flat_map(move |x| [(4 * x + y) as u8, (3 * y + 40) as u8, (200 - 2 * x) as u8])
        })
        .collect()
}

fn gray() -> Plane {
    let data = (0..H)
        .flat_map(|y| (0..W).map(move |x| (x * 5 + y * 2) as u8))
        .collect();
    Plane::new(W, H, data)
}

fn surface() -> Surface {
    let values: Vec<u16> = (0..H)
        .flat_map(|y| (0..W).map(move |x| (1000 + 37 * x + 11 * y) as u16))
        .collect();
    let img = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_raw(W, H, values).unwrap();
    Surface::of_gray16(&image::DynamicImage::ImageLuma16(img)).unwrap()
}

/// The stream of `image` at 1 bpp through `Loaded::analyse`.
fn stream(image: Loaded) -> Vec<u8> {
    assert_eq!(image.size(), (W, H));
    (image.analyse(&EncoderConfig::default(), &|_| {}))
        .unwrap()
        .encode(Target::Bpp(1.0))
        .unwrap()
        .bytes
}

#[test]
fn every_kind_of_image_makes_its_own_streams() {
    let config = EncoderConfig::default();
    let one = |analysis: host_encoder::Analysis| analysis.encode(Target::Bpp(1.0)).unwrap().bytes;

    let gray_stream = stream(Loaded::Gray(gray()));
    assert_eq!(gray_stream, one(analyse(gray(), &config, &|_| {}).unwrap()));
    assert_eq!(Decoder::new(&gray_stream).unwrap().header().channels, 1);

    let colour = Loaded::Rgb {
        width: W,
        height: H,
        data: rgb(),
    };
    let colour_stream = stream(colour);
    assert_eq!(
        colour_stream,
        one(analyse_colour(W, H, rgb(), &config, &|_| {}).unwrap())
    );
    assert_eq!(Decoder::new(&colour_stream).unwrap().header().channels, 3);

    let surface_stream = stream(Loaded::Surface(surface()));
    let ranged = EncoderConfig {
        range: Some(surface().range()),
        ..EncoderConfig::default()
    };
    assert_eq!(
        surface_stream,
        one(analyse(surface().plane(), &ranged, &|_| {}).unwrap())
    );
    let header = *Decoder::new(&surface_stream).unwrap().header();
    assert_eq!(header.range, Some(surface().range()));
}
