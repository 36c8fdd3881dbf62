//! Fuzz target: see `pifs_tests::fuzz::stream_equals_slice`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| pifs_tests::fuzz::stream_equals_slice(data));
