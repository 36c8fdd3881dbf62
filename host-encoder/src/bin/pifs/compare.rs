//! Rate/distortion points of other codecs, read from a CSV file for `pifs rd --compare`.
//!
//! The file has a header row; the columns are found by name, in any order:
//! - required: `codec`, `bpp` (whole-file bits per pixel), `psnr` (dB);
//! - optional: `status` (rows other than `ok` are left out), `image` and `target_bpp`.
//!
//! This reads the CSV of `anchors.py` (one row per image, codec and target) as well as the one
//! `pifs rd --csv` writes. When an `image` column names the image being analysed (its file name
//! or stem), only its rows are drawn; when it names several other images, each codec's points
//! are averaged per target (the means of the anchors' report); otherwise every row is a point.

use std::collections::BTreeMap;

/// One codec's points, (bpp, PSNR dB), by increasing rate.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// The legend's name.
    pub name: String,
    /// The points.
    pub points: Vec<(f64, f64)>,
}

/// Splits one CSV line into fields: commas separate, double quotes enclose a field that may
/// hold commas, and a doubled quote inside stands for one.
pub fn fields(line: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut field = String::new();
    let mut quoted = false;
    let mut chars = line.chars().peekable();
    while let Some(c) = chars.next() {
        match (c, quoted) {
            ('"', true) if chars.peek() == Some(&'"') => {
                field.push('"');
                chars.next();
            }
            ('"', true) => quoted = false,
            ('"', false) if field.is_empty() => quoted = true,
            (',', false) => out.push(std::mem::take(&mut field)),
            _ => field.push(c),
        }
    }
    out.push(field);
    out
}

/// A row's numbers and labels.
struct Row {
    codec: String,
    bpp: f64,
    psnr: f64,
    image: Option<String>,
    target: Option<String>,
}

/// The file name without its extension.
fn stem(name: &str) -> &str {
    let base = name.rsplit(['/', '\\']).next().unwrap_or(name);
    base.rsplit_once('.').map_or(base, |(s, _)| s)
}

/// Reads the series of `text`; `image` is the file name of the image analysed. The error
/// says what is missing.
pub fn parse(text: &str, image: &str) -> Result<Vec<Series>, String> {
    let mut lines = text.lines().filter(|l| !l.trim().is_empty());
    let header: Vec<String> = fields(lines.next().ok_or("the file is empty")?)
        .iter()
        .map(|h| h.trim().to_ascii_lowercase())
        .collect();
    let column = |name: &str| header.iter().position(|h| h == name);
    let required = |name: &str| {
        column(name).ok_or_else(|| format!("no '{name}' column (need codec, bpp and psnr)"))
    };
    let (codec, bpp, psnr) = (required("codec")?, required("bpp")?, required("psnr")?);
    let (status, image_col, target) = (column("status"), column("image"), column("target_bpp"));
    let rows: Vec<Row> = lines
        .filter_map(|line| {
            let f = fields(line);
            let get = |i: usize| f.get(i).map(|s| s.trim().to_string());
            if let Some(s) = status.and_then(get) {
                if !(s.is_empty() || s.eq_ignore_ascii_case("ok")) {
                    return None;
                }
            }
            let number = |i| get(i)?.parse::<f64>().ok().filter(|v| v.is_finite());
            Some(Row {
                codec: get(codec).filter(|c| !c.is_empty())?,
                bpp: number(bpp)?,
                psnr: number(psnr)?,
                image: image_col.and_then(get),
                target: target.and_then(get),
            })
        })
        .collect();
    let this_image = |r: &Row| {
        r.image
            .as_deref()
            .is_some_and(|i| i == image || stem(i) == stem(image))
    };
    let mine: Vec<&Row> = rows.iter().filter(|r| this_image(r)).collect();
    let images: std::collections::BTreeSet<&str> =
        rows.iter().filter_map(|r| r.image.as_deref()).collect();
    let series = if !mine.is_empty() {
        group(&mine, |r| r.codec.clone(), false)
    } else if images.len() > 1 && target.is_some() {
        group(&rows.iter().collect::<Vec<_>>(), |r| r.codec.clone(), true)
    } else {
        group(&rows.iter().collect::<Vec<_>>(), |r| r.codec.clone(), false)
    };
    if series.is_empty() {
        return Err("no usable rows (codec, bpp and psnr numbers, status ok)".into());
    }
    Ok(series)
}

/// The rows by codec (in order of first appearance), as points, or with `mean` as the mean
/// point of each target.
fn group(rows: &[&Row], key: impl Fn(&Row) -> String, mean: bool) -> Vec<Series> {
    let mut order: Vec<String> = Vec::new();
    let mut by_codec: BTreeMap<String, Vec<&Row>> = BTreeMap::new();
    for r in rows {
        let k = key(r);
        if !by_codec.contains_key(&k) {
            order.push(k.clone());
        }
        by_codec.entry(k).or_default().push(r);
    }
    order
        .into_iter()
        .map(|codec| {
            let rows = &by_codec[&codec];
            let mut points: Vec<(f64, f64)> = if mean {
                let mut per_target: BTreeMap<&str, (f64, f64, usize)> = BTreeMap::new();
                for r in rows {
                    let e = per_target
                        .entry(r.target.as_deref().unwrap_or(""))
                        .or_default();
                    *e = (e.0 + r.bpp, e.1 + r.psnr, e.2 + 1);
                }
                per_target
                    .values()
                    .map(|&(b, p, n)| (b / n as f64, p / n as f64))
                    .collect()
            } else {
                rows.iter().map(|r| (r.bpp, r.psnr)).collect()
            };
            points.sort_by(|a, b| a.0.total_cmp(&b.0));
            let name = if mean {
                let n: std::collections::BTreeSet<&str> =
                    rows.iter().filter_map(|r| r.image.as_deref()).collect();
                format!("{codec} (mean of {} images)", n.len())
            } else {
                codec
            };
            Series { name, points }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    const ANCHORS: &str = "\
set,image,width,height,codec,target_bpp,status,param,bytes,bpp,psnr,psnr_interp,enc_s,dec_s,n_encodes,note
kodak,kodim01.png,768,512,jpeg,0.1,ok,q=5,4900,0.09970,24.1000,24.2,0.01,0.01,7,
kodak,kodim01.png,768,512,jpeg,0.05,unreachable,q=1,3000,0.06100,,,,,1,\"lowest setting gives 0.0610 bpp, sorry\"
kodak,kodim01.png,768,512,jpeg2000,0.1,ok,p=7.9,4910,0.09990,26.0000,26.0,0.07,0.01,9,
kodak,kodim02.png,768,512,jpeg,0.1,ok,q=6,4800,0.09770,28.1000,28.2,0.01,0.01,7,
kodak,kodim02.png,768,512,jpeg2000,0.1,ok,p=7.8,4900,0.09970,30.0000,30.0,0.07,0.01,9,
";

    #[test]
    fn fields_honour_quotes() {
        assert_eq!(fields("a,\"b,c\",\"d\"\"e\","), ["a", "b,c", "d\"e", ""]);
    }

    #[test]
    fn the_analysed_image_gets_its_own_rows() {
        let s = parse(ANCHORS, "kodim02.png").unwrap();
        assert_eq!(s.len(), 2);
        assert_eq!(s[0].name, "jpeg");
        assert_eq!(s[0].points, [(0.0977, 28.1)]);
        assert_eq!(s[1].points, [(0.0997, 30.0)]);
        // Matched by stem too, whatever the extension of the analysed file.
        assert_eq!(
            parse(ANCHORS, "/x/kodim01.pgm").unwrap()[0].points,
            [(0.0997, 24.1)]
        );
    }

    #[test]
    fn other_images_give_the_mean_per_target_and_failures_are_left_out() {
        let s = parse(ANCHORS, "mine.png").unwrap();
        assert_eq!(s[0].name, "jpeg (mean of 2 images)");
        assert_eq!(s[0].points.len(), 1, "the unreachable row is left out");
        let (b, p) = s[0].points[0];
        assert!((b - 0.0987).abs() < 1e-9 && (p - 26.1).abs() < 1e-9);
    }

    #[test]
    fn the_minimal_format_is_codec_bpp_psnr() {
        let s = parse(
            "codec,bpp,psnr,bytes\npifs,0.25,30.5,100\npifs,0.1,27,40\n",
            "a.png",
        )
        .unwrap();
        assert_eq!(s[0].points, [(0.1, 27.0), (0.25, 30.5)]);
        let err = parse("codec,rate,psnr\nx,1,2\n", "a.png").unwrap_err();
        assert!(err.contains("'bpp'"), "{err}");
        assert!(parse("codec,bpp,psnr\n", "a.png").is_err());
    }
}
