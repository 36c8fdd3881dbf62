//! 16-bit surfaces through the library: the analysis fits the samples at 1/16 of a grey level
//! (`Plane::with_samples`), not their rounding to grey, and the stream's values are nearer the
//! data for it.

use decoder_core::Decoder;
use host_encoder::io::Surface;
use host_encoder::{analyse, EncoderConfig, Plane, Target};

/// A smooth 96x80 surface spanning 500 units (a grey level is about 2 of them), with a ridge.
fn surface() -> Surface {
    let (w, h) = (96u32, 80u32);
    let height = |x: u32, y: u32| {
        let (x, y) = (f64::from(x), f64::from(y));
        let ridge = 120.0 * (-((x - 0.8 * y - 20.0) / 9.0).powi(2)).exp();
        2000.0 + 180.0 * (x / 17.0).sin() * (y / 23.0).cos() + 1.5 * x + ridge
    };
    let values: Vec<u16> = (0..h)
        .flat_map(|y| (0..w).map(move |x| height(x, y).round() as u16))
        .collect();
    let img = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_raw(w, h, values).unwrap();
    Surface::of_gray16(&image::DynamicImage::ImageLuma16(img)).unwrap()
}

/// RMSE of the values of a 16-bit stream of `plane` at `bpp` against the surface.
fn rmse(surface: &Surface, plane: Plane, bpp: f64) -> f64 {
    let config = EncoderConfig {
        range: Some(surface.range()),
        ..EncoderConfig::default()
    };
    let encoded = analyse(plane, &config, &|_| {})
        .unwrap()
        .encode(Target::Bpp(bpp))
        .unwrap();
    let mut values = vec![0u16; surface.values.len()];
    Decoder::new(&encoded.bytes)
        .unwrap()
        .decode_values_into(&mut values)
        .unwrap();
    surface.error(&values).rmse
}

#[test]
fn surfaces_are_fitted_finer_than_grey() {
    let surface = surface();
    let plane = surface.plane();
    let fine = plane
        .fine
        .as_ref()
        .expect("a surface's plane has fine samples");
    // The samples are the grey levels, to 1/16, and round to the plane's pixels.
    assert!(fine.iter().any(|s| s % 16 != 0));
    for (&s, &p) in fine.iter().zip(&plane.data) {
        assert_eq!(((s + 8) >> 4) as u8, p);
    }
    let coarse = Plane::new(plane.width, plane.height, plane.data.clone());
    for bpp in [1.0, 2.0] {
        let (fine, coarse) = (
            rmse(&surface, plane.clone(), bpp),
            rmse(&surface, coarse.clone(), bpp),
        );
        // At rates where leaves code nearly every pixel, the grey rounding of the targets is a
        // good part of the error.
        assert!(
            fine < coarse,
            "{bpp} bpp: RMSE {fine} with fine targets, {coarse} without"
        );
    }
}

/// A quality target on a surface is the PSNR of its range, measured on the stream's values.
#[test]
fn a_surfaces_quality_target_is_the_psnr_of_its_range() {
    let surface = surface();
    let config = EncoderConfig {
        range: Some(surface.range()),
        ..EncoderConfig::default()
    };
    let analysis = analyse(surface.plane(), &config, &|_| {}).unwrap();
    for target in [36.0, 44.0] {
        let encoded = analysis.encode(Target::Psnr(target)).unwrap();
        let mut values = vec![0u16; surface.values.len()];
        Decoder::new(&encoded.bytes)
            .unwrap()
            .decode_values_into(&mut values)
            .unwrap();
        let measured = surface.error(&values).psnr;
        // The stream's own figure: its values against the surface at 1/16 of a grey level,
        // whose range is the data's to within a step (0.02 dB here).
        assert!(
            (encoded.psnr - measured).abs() < 0.05,
            "{} vs {measured}",
            encoded.psnr
        );
        assert!(
            measured >= target - 0.05,
            "{target} dB asked, {measured} reached"
        );
    }
}
