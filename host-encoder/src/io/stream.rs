//! PIFS streams in, decoded images out, with memory that follows the image's width.
//!
//! [`StreamInput::open`] reads a stream header first: bytes that are not a stream are refused
//! after at most a header's worth (`/dev/zero` after four), a stream beyond the caller's
//! [`Limits`] on its header alone, and then exactly the declared payload is read (from a
//! regular file its length is checked without reading, and its checksum streamed; from a pipe
//! or a device the payload is held in memory, growing only as bytes arrive). Nothing is decoded
//! before the stream's length and checksum are known to be right, so a damaged stream draws
//! nothing anywhere.
//!
//! [`decode_to_image`] writes the image row by row ([`ImageWriter`]) from a band of rows in
//! memory ([`BAND_BYTES`]): each row is written as soon as every leaf covering it has been
//! drawn. When the decoder's coding order reaches below the band before the band's top row is
//! complete (a quadtree in Z order over a large image does), the stream is decoded again for
//! each band with [`Decoder::clip`], the entropy decoding repeated and the pixels drawn once
//! (measurements: `docs/decisions.md`, "Decoded images written band by band").

use super::image_out::{ImageWriter, OutputFormat};
use super::{input_name, is_std_stream, FileError};
use decoder_core::internal::checksum::Crc32;
use decoder_core::internal::syntax::CHECKSUM_BYTES;
use decoder_core::{
    ByteSource, DecodeError, Decoder, DrawError, Header, HeaderField, Limits, PixelSink, Rect,
    Scale, Streamed, Tile, MAX_HEADER_LEN,
};
use std::cell::RefCell;
use std::fs::File;
use std::io::{BufReader, Read, Write};
use std::path::{Path, PathBuf};
use std::rc::Rc;

/// Memory for the rows of a band being decoded (at least a leaf's height of rows, whatever
/// the width): 32 MiB, 2048 rows of a 16384-pixel-wide image.
pub const BAND_BYTES: usize = 32 << 20;

/// The widest stripe a host decodes: any the format allows (one byte per column, on the stack
/// while decoding).
pub const HOST_STRIPE: usize = 1 << 16;

/// The tallest leaf: a band holds at least this many rows (at the coded size).
const MIN_BAND_ROWS: u32 = 1 << decoder_core::internal::format::MAX_LEAF_LOG2;

/// A checked stream, ready to be decoded any number of times.
#[derive(Debug)]
pub struct StreamInput {
    /// The input as the user named it.
    name: PathBuf,
    header: Header,
    bytes: Stored,
}

#[derive(Debug)]
enum Stored {
    /// A regular file, read again for each decode.
    File(PathBuf),
    /// The stream, whole.
    Memory(Vec<u8>),
}

impl StreamInput {
    /// Reads the stream at `path` (`-`: standard input) header first, by the rules of this
    /// module, refusing it when its header is beyond `limits`. A regular file is checked here
    /// (length, checksum) and read again for each decode; anything else is held in memory.
    pub fn open(path: &Path, limits: &Limits) -> Result<StreamInput, FileError> {
        let name = input_name(path);
        if is_std_stream(path) {
            return StreamInput::from_reader(std::io::stdin().lock(), &name, limits);
        }
        if path.is_dir() {
            return Err(FileError::IsDirectory {
                path: name,
                expected: "a .pifs stream",
            });
        }
        let file = File::open(path).map_err(|source| FileError::Read {
            path: name.clone(),
            source,
        })?;
        let len = match file.metadata() {
            Ok(m) if m.is_file() => m.len(),
            _ => return StreamInput::from_reader(BufReader::new(file), &name, limits),
        };
        let mut reader = BufReader::new(file);
        let (header, _, mut crc) = checked_header(&mut reader, &name, limits)?;
        let refused = |source| FileError::Stream {
            path: name.clone(),
            source,
        };
        let stream_len = header.stream_len();
        if len < stream_len {
            return Err(refused(DecodeError::Truncated));
        }
        if len > stream_len {
            return Err(refused(DecodeError::InvalidHeader(
                HeaderField::TrailingBytes,
            )));
        }
        let mut buf = vec![0u8; 1 << 16];
        let mut left = u64::from(header.payload_len);
        while left > 0 {
            let want = buf.len().min(usize::try_from(left).unwrap_or(usize::MAX));
            let n = reader
                .read(&mut buf[..want])
                .map_err(|source| FileError::Read {
                    path: name.clone(),
                    source,
                })?;
            if n == 0 {
                return Err(refused(DecodeError::Truncated));
            }
            crc.update(&buf[..n]);
            left -= n as u64;
        }
        check_crc(&header, crc).map_err(refused)?;
        Ok(StreamInput {
            name,
            header,
            bytes: Stored::File(path.to_path_buf()),
        })
    }

    /// Reads a stream from `reader` header first (`name` names it in errors), refusing it when
    /// its header is beyond `limits`, then exactly the payload the header declares (held in
    /// memory, which grows only as bytes arrive) and one byte more, which must not be there.
    /// At most the header, the payload and that one byte are read.
    pub fn from_reader(
        mut reader: impl Read,
        name: &Path,
        limits: &Limits,
    ) -> Result<StreamInput, FileError> {
        let (header, mut data, mut crc) = checked_header(&mut reader, name, limits)?;
        let read_failed = |source| FileError::Read {
            path: name.to_path_buf(),
            source,
        };
        let refused = |source| FileError::Stream {
            path: name.to_path_buf(),
            source,
        };
        let head_len = data.len();
        (&mut reader)
            .take(u64::from(header.payload_len))
            .read_to_end(&mut data)
            .map_err(read_failed)?;
        if (data.len() as u64) < header.stream_len() {
            return Err(refused(DecodeError::Truncated));
        }
        let mut one = [0u8; 1];
        let extra = loop {
            match reader.read(&mut one) {
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                other => break other.map_err(read_failed)?,
            }
        };
        if extra != 0 {
            return Err(refused(DecodeError::InvalidHeader(
                HeaderField::TrailingBytes,
            )));
        }
        crc.update(&data[head_len..]);
        check_crc(&header, crc).map_err(refused)?;
        Ok(StreamInput {
            name: name.to_path_buf(),
            header,
            bytes: Stored::Memory(data),
        })
    }

    /// The stream's header.
    pub fn header(&self) -> &Header {
        &self.header
    }

    /// The input as the user named it ("standard input" for `-`).
    pub fn name(&self) -> &Path {
        &self.name
    }

    /// The stream's length, bytes.
    pub fn len(&self) -> u64 {
        self.header.stream_len()
    }

    /// Whether the stream is empty (never: a stream has a header).
    pub fn is_empty(&self) -> bool {
        false
    }

    /// A decoder of the stream, and the slot where a read error of the file it comes from
    /// is kept (the decoder itself only sees the stream end early).
    #[allow(clippy::type_complexity)]
    pub fn decoder(
        &self,
    ) -> Result<
        (
            Decoder<Streamed<Bytes<'_>>, fn(&decoder_core::LeafInfo), HOST_STRIPE>,
            ReadFailure,
        ),
        FileError,
    > {
        let failure = ReadFailure::default();
        let inner = match &self.bytes {
            Stored::Memory(data) => Inner::Slice(data, 0),
            Stored::File(path) => {
                let file = File::open(path).map_err(|source| FileError::Read {
                    path: self.name.clone(),
                    source,
                })?;
                Inner::File {
                    file,
                    buf: vec![0; 1 << 16],
                    pos: 0,
                    len: 0,
                }
            }
        };
        let bytes = Bytes {
            inner,
            failure: failure.clone(),
        };
        let decoder = Decoder::from_source(bytes).map_err(|e| self.error(e, &failure))?;
        Ok((decoder.stripe_capacity::<HOST_STRIPE>(), failure))
    }

    /// The error of a decode that failed with `e`: the read error behind it if there was one.
    pub fn error(&self, e: DecodeError, failure: &ReadFailure) -> FileError {
        match failure.0.borrow_mut().take() {
            Some(source) => FileError::Read {
                path: self.name.clone(),
                source,
            },
            None => FileError::Stream {
                path: self.name.clone(),
                source: e,
            },
        }
    }

    /// Entropy-decodes the whole stream without drawing a pixel (only the edge pixels later
    /// leaves are predicted from), calling `observer` for every leaf.
    pub fn verify(
        &self,
        observer: impl FnMut(&decoder_core::LeafInfo),
    ) -> Result<Header, FileError> {
        let (decoder, failure) = self.decoder()?;
        decoder
            .observe(observer)
            .verify()
            .map_err(|e| self.error(e, &failure))
    }
}

/// Where a decode's source keeps the read error that ended it early.
#[derive(Debug, Default, Clone)]
pub struct ReadFailure(Rc<RefCell<Option<std::io::Error>>>);

/// The bytes of a [`StreamInput`], for the decoder.
#[derive(Debug)]
pub struct Bytes<'a> {
    inner: Inner<'a>,
    failure: ReadFailure,
}

#[derive(Debug)]
enum Inner<'a> {
    Slice(&'a [u8], usize),
    File {
        file: File,
        buf: Vec<u8>,
        pos: usize,
        len: usize,
    },
}

impl ByteSource for Bytes<'_> {
    #[inline]
    fn next_byte(&mut self) -> Option<u8> {
        match &mut self.inner {
            Inner::Slice(data, pos) => {
                let b = data.get(*pos).copied();
                *pos += 1;
                b
            }
            Inner::File {
                file,
                buf,
                pos,
                len,
            } => {
                if *pos == *len {
                    *pos = 0;
                    *len = loop {
                        match file.read(buf) {
                            Ok(n) => break n,
                            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                            Err(e) => {
                                *self.failure.0.borrow_mut() = Some(e);
                                break 0;
                            }
                        }
                    };
                    if *len == 0 {
                        return None;
                    }
                }
                let b = buf[*pos];
                *pos += 1;
                Some(b)
            }
        }
    }
}

enum HeaderRead {
    Io(std::io::Error),
    Stream(DecodeError),
}

/// What bytes that are not a stream of this version are, once `head` (the bytes read so far)
/// failed as a stream: a stream of format 21 or earlier (`PIFS` and its version byte, read from
/// `reader` as far as it takes to tell) is [`DecodeError::UnsupportedVersion`], anything else
/// [`DecodeError::BadMagic`].
fn legacy_version(reader: &mut dyn Read, mut head: Vec<u8>) -> DecodeError {
    let magic = decoder_core::internal::format::LEGACY_MAGIC;
    // Read on while the bytes so far agree with `PIFS`, up to the version byte after it.
    while head.len() <= magic.len() && magic.iter().zip(&head).all(|(a, b)| a == b) {
        let mut one = [0u8; 1];
        match reader.read(&mut one) {
            Ok(1) => head.push(one[0]),
            _ => return DecodeError::BadMagic,
        }
    }
    match head.get(magic.len()) {
        Some(&version) if head.starts_with(&magic) => DecodeError::UnsupportedVersion(version),
        _ => DecodeError::BadMagic,
    }
}

/// Reads a header's bytes one at a time while [`Header::parse`] asks for more, so that input
/// that is not a stream is refused as soon as it shows (at its first byte, unless that byte
/// opens a stream) and nothing past the header is read. Returns the header and its bytes.
fn read_header(reader: &mut dyn Read) -> Result<(Header, Vec<u8>), HeaderRead> {
    let mut head = Vec::with_capacity(MAX_HEADER_LEN);
    loop {
        match Header::parse(&head) {
            Ok((header, len)) => {
                head.truncate(len);
                return Ok((header, head));
            }
            Err(DecodeError::Truncated) if head.len() < MAX_HEADER_LEN => {
                let mut one = [0u8; 1];
                let n = loop {
                    match reader.read(&mut one) {
                        Ok(n) => break n,
                        Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                        Err(e) => return Err(HeaderRead::Io(e)),
                    }
                };
                if n == 0 {
                    return Err(HeaderRead::Stream(DecodeError::Truncated));
                }
                head.push(one[0]);
            }
            Err(DecodeError::BadMagic) => {
                return Err(HeaderRead::Stream(legacy_version(reader, head)))
            }
            Err(e) => return Err(HeaderRead::Stream(e)),
        }
    }
}

/// Reads and checks a header from `reader` (`name` names it in errors) and checks it against
/// `limits`; returns it, its bytes and the CRC-32 state after its checksummed bytes.
fn checked_header(
    reader: &mut dyn Read,
    name: &Path,
    limits: &Limits,
) -> Result<(Header, Vec<u8>, Crc32), FileError> {
    let (header, head) = read_header(reader).map_err(|e| match e {
        HeaderRead::Io(source) => FileError::Read {
            path: name.to_path_buf(),
            source,
        },
        HeaderRead::Stream(source) => FileError::Stream {
            path: name.to_path_buf(),
            source,
        },
    })?;
    limits.check(&header).map_err(|source| FileError::Stream {
        path: name.to_path_buf(),
        source,
    })?;
    let mut crc = Crc32::default();
    crc.update(&head[..CHECKSUM_BYTES.start]);
    crc.update(&head[CHECKSUM_BYTES.end..]);
    Ok((header, head, crc))
}

/// `Ok` when `crc` (the whole stream's but the checksum field's) is the header's checksum.
fn check_crc(header: &Header, crc: Crc32) -> Result<(), DecodeError> {
    let computed = crc.value();
    if computed != header.checksum {
        return Err(DecodeError::ChecksumMismatch {
            stored: header.checksum,
            computed,
        });
    }
    Ok(())
}

/// Reads the stream at `path` whole into memory, header first (see [`StreamInput::open`]),
/// within `limits`.
pub fn read_stream(path: &Path, limits: &Limits) -> Result<Vec<u8>, FileError> {
    let input = StreamInput::open(path, limits)?;
    match input.bytes {
        Stored::Memory(data) => Ok(data),
        Stored::File(file) => std::fs::read(&file).map_err(|source| FileError::Read {
            path: input.name,
            source,
        }),
    }
}

/// Why a band's sink stopped the decoder.
#[derive(Debug)]
enum Stop {
    /// A tile below the band: the coding order needs a band per decode.
    BelowBand,
    /// Every row of a band that is not the image's last was written: the rest of the stream
    /// is not needed for it.
    BandDone,
    /// Writing a row failed.
    Write(std::io::Error),
}

/// Rows of the image in memory, from `base` (the first row not yet written) down, in a ring.
struct Band<'w, W: Write + 'static> {
    width: usize,
    /// Samples a pixel (1 or 3).
    channels: usize,
    /// Rows the ring holds.
    rows: u32,
    ring: Vec<u8>,
    /// Pixels drawn in each row of the ring.
    drawn: Vec<u32>,
    base: u32,
    /// Rows of the current decode's clip end here.
    end: u32,
    /// Stop when the clip's rows are all written.
    stop_at_end: bool,
    writer: &'w mut ImageWriter<W>,
}

impl<W: Write + 'static> Band<'_, W> {
    fn slot(&self, row: u32) -> usize {
        (row % self.rows) as usize
    }
}

impl<W: Write + 'static> PixelSink for Band<'_, W> {
    type Error = Stop;

    fn tile(&mut self, tile: Tile<'_>) -> Result<(), Stop> {
        let Rect { x, y, w, h } = tile.area;
        if w == 0 || h == 0 {
            return Ok(());
        }
        if y < self.base || y + h > self.base + self.rows {
            return Err(Stop::BelowBand);
        }
        let (c, row_len) = (self.channels, self.width * self.channels);
        for (r, src) in tile.pixels.chunks_exact(w as usize * c).enumerate() {
            let slot = self.slot(y + r as u32);
            let start = slot * row_len + x as usize * c;
            self.ring[start..start + src.len()].copy_from_slice(src);
            self.drawn[slot] += w;
        }
        while self.base < self.end && self.drawn[self.slot(self.base)] as usize >= self.width {
            let slot = self.slot(self.base);
            self.writer
                .write_row(&self.ring[slot * row_len..(slot + 1) * row_len])
                .map_err(Stop::Write)?;
            self.drawn[slot] = 0;
            self.base += 1;
        }
        if self.stop_at_end && self.base == self.end {
            return Err(Stop::BandDone);
        }
        Ok(())
    }
}

/// What [`decode_to_image`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Decoded {
    /// The stream's header.
    pub header: Header,
    /// Width of the image written (the header's at the decode's scale).
    pub width: u32,
    /// Height of the image written.
    pub height: u32,
    /// Times the stream was decoded (1 when rows could be written as the decoder went).
    pub passes: u32,
}

/// Decodes `input` and writes it to `out` as an image in `format`, row by row, holding at most
/// `band_bytes` of rows (and at least a leaf's height of rows) in memory; hands `out` back.
/// Write errors are [`FileError::Write`] naming `out_name`.
pub fn decode_to_image<W: Write + 'static>(
    input: &StreamInput,
    format: OutputFormat,
    scale: Scale,
    out: W,
    out_name: &Path,
    band_bytes: usize,
) -> Result<(Decoded, W), FileError> {
    let header = *input.header();
    let (width, height) = (
        scale.apply(header.width.into()),
        scale.apply(header.height.into()),
    );
    let write_failed = |source| FileError::Write {
        path: out_name.to_path_buf(),
        source,
    };
    let broken = |why: &str| FileError::Read {
        path: input.name.clone(),
        source: std::io::Error::other(format!("internal error: {why}")),
    };
    let channels = header.channels;
    let row_len = width as usize * usize::from(channels);
    let rows = u32::try_from(band_bytes / row_len)
        .unwrap_or(u32::MAX)
        .max(scale.apply(MIN_BAND_ROWS))
        .min(height);
    let mut writer =
        ImageWriter::new(format, out, width, height, channels).map_err(write_failed)?;
    let mut band = Band {
        width: width as usize,
        channels: usize::from(channels),
        rows,
        ring: vec![0; rows as usize * row_len],
        drawn: vec![0; rows as usize],
        base: 0,
        end: height,
        stop_at_end: false,
        writer: &mut writer,
    };
    // First as the decoder goes; once its order reaches below the band, a decode per band.
    let mut follow = true;
    let mut passes = 0;
    while band.base < height {
        passes += 1;
        let top = band.base;
        band.end = if follow {
            height
        } else {
            (top + rows).min(height)
        };
        band.stop_at_end = band.end < height;
        band.drawn.iter_mut().for_each(|d| *d = 0);
        let (decoder, failure) = input.decoder()?;
        let clip = Rect {
            x: 0,
            y: top,
            w: width,
            h: band.end - top,
        };
        match decoder.scale(scale).clip(clip).decode(&mut band) {
            Ok(_) => {
                if band.base < band.end {
                    // A decode that ends without an error has drawn every pixel of its clip.
                    return Err(broken("a decode ended with rows of its clip not drawn"));
                }
            }
            Err(DrawError::Sink(Stop::BandDone)) => {}
            Err(DrawError::Sink(Stop::BelowBand)) if follow => follow = false,
            Err(DrawError::Sink(Stop::BelowBand)) => {
                return Err(broken("the decoder drew outside its clip or a pixel twice"))
            }
            Err(DrawError::Sink(Stop::Write(e))) => return Err(write_failed(e)),
            Err(DrawError::Decode(e)) => return Err(input.error(e, &failure)),
        }
    }
    let out = writer.finish().map_err(write_failed)?;
    Ok((
        Decoded {
            header,
            width,
            height,
            passes,
        },
        out,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::internal::synthetic_stream;

    /// Counts the bytes a reader hands out.
    struct Counting<'a> {
        data: &'a [u8],
        pulled: usize,
    }

    impl Read for Counting<'_> {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            let n = buf.len().min(self.data.len() - self.pulled);
            buf[..n].copy_from_slice(&self.data[self.pulled..self.pulled + n]);
            self.pulled += n;
            Ok(n)
        }
    }

    fn stream(w: u16, h: u16, leaf_log2: u8) -> Vec<u8> {
        synthetic_stream(w, h, leaf_log2, |node, leaf| {
            leaf.control[0] = ((node.x / 4 + node.y / 8) % 7) as i16 - 3;
            leaf.control[1] = ((node.x / 16 + node.y / 4) % 5) as i16 - 2;
        })
        .unwrap()
    }

    fn reference(bytes: &[u8]) -> Vec<u8> {
        let decoder = Decoder::new(bytes).unwrap();
        let mut px = vec![0u8; decoder.header().pixel_count()];
        decoder.decode_into(&mut px).unwrap();
        px
    }

    fn name() -> &'static Path {
        Path::new("test.pifs")
    }

    #[test]
    fn what_is_not_a_stream_is_refused_at_its_first_byte() {
        let zeros = vec![0u8; 1 << 16];
        let mut source = Counting {
            data: &zeros,
            pulled: 0,
        };
        let err = StreamInput::from_reader(&mut source, name(), &Limits::NONE).unwrap_err();
        assert!(
            matches!(
                err,
                FileError::Stream {
                    source: DecodeError::BadMagic,
                    ..
                }
            ),
            "{err}"
        );
        assert_eq!(source.pulled, 1);
    }

    #[test]
    fn a_stream_beyond_the_limits_is_refused_on_its_header() {
        let bytes = stream(300, 200, 5);
        let header = Header::read(&bytes).unwrap();
        let mut source = Counting {
            data: &bytes,
            pulled: 0,
        };
        let err =
            StreamInput::from_reader(&mut source, name(), &Limits::pixels(59_999)).unwrap_err();
        assert!(
            matches!(
                err,
                FileError::Stream {
                    source: DecodeError::TooLarge { .. },
                    ..
                }
            ),
            "{err}"
        );
        assert_eq!(source.pulled, header.encoded_len());
    }

    #[test]
    fn at_most_the_stream_and_one_byte_are_read() {
        let bytes = stream(64, 40, 4);
        let mut longer = bytes.clone();
        longer.extend_from_slice(&[0; 1000]);
        let mut source = Counting {
            data: &longer,
            pulled: 0,
        };
        let err = StreamInput::from_reader(&mut source, name(), &Limits::NONE).unwrap_err();
        assert!(
            matches!(
                err,
                FileError::Stream {
                    source: DecodeError::InvalidHeader(HeaderField::TrailingBytes),
                    ..
                }
            ),
            "{err}"
        );
        assert_eq!(source.pulled, bytes.len() + 1);
        let short = &bytes[..bytes.len() - 1];
        let err = StreamInput::from_reader(short, name(), &Limits::NONE).unwrap_err();
        assert!(
            matches!(
                err,
                FileError::Stream {
                    source: DecodeError::Truncated,
                    ..
                }
            ),
            "{err}"
        );
        let mut damaged = bytes.clone();
        let last = damaged.len() - 1;
        damaged[last] ^= 1;
        let err = StreamInput::from_reader(&damaged[..], name(), &Limits::NONE).unwrap_err();
        assert!(
            matches!(
                err,
                FileError::Stream {
                    source: DecodeError::ChecksumMismatch { .. },
                    ..
                }
            ),
            "{err}"
        );
    }

    /// Band by band, in one pass or several, from memory or from a file: the pixels of
    /// `decode_into`.
    #[test]
    fn the_image_written_by_bands_is_the_decoded_image() {
        let dir = tempfile::tempdir().unwrap();
        for (w, h, leaf, band, passes) in [
            (64u16, 40u16, 4u8, BAND_BYTES, 1u32),
            (200, 700, 3, 1, 7),
            (300, 1000, 7, 200 * 300, 9),
            (1, 300, 2, 1, 4),
            (513, 129, 6, 1, 3),
        ] {
            let bytes = stream(w, h, leaf);
            let want = reference(&bytes);
            let path = dir.path().join("s.pifs");
            std::fs::write(&path, &bytes).unwrap();
            for input in [
                StreamInput::from_reader(&bytes[..], name(), &Limits::NONE).unwrap(),
                StreamInput::open(&path, &Limits::NONE).unwrap(),
            ] {
                let (decoded, pgm) = decode_to_image(
                    &input,
                    OutputFormat::Pgm,
                    Scale::One,
                    Vec::new(),
                    name(),
                    band,
                )
                .unwrap();
                let head = format!("P5\n{w} {h}\n255\n");
                assert!(pgm.starts_with(head.as_bytes()));
                assert!(pgm[head.len()..] == want[..], "{w}x{h} leaf {leaf}");
                assert!(
                    decoded.passes <= passes,
                    "{w}x{h}: {} passes",
                    decoded.passes
                );
            }
        }
    }

    #[test]
    fn a_failing_output_stops_the_decode_with_its_error() {
        struct Full;
        impl std::io::Write for Full {
            fn write(&mut self, _: &[u8]) -> std::io::Result<usize> {
                Err(std::io::Error::from(std::io::ErrorKind::StorageFull))
            }
            fn flush(&mut self) -> std::io::Result<()> {
                Ok(())
            }
        }
        let bytes = stream(64, 300, 5);
        let input = StreamInput::from_reader(&bytes[..], name(), &Limits::NONE).unwrap();
        let err = decode_to_image(
            &input,
            OutputFormat::Pgm,
            Scale::One,
            Full,
            Path::new("out.pgm"),
            1,
        )
        .err()
        .unwrap();
        assert!(
            err.to_string().starts_with("cannot write out.pgm: "),
            "{err}"
        );
    }
}
