//! Fuzz target: see `pifs_tests::fuzz::roundtrip`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| pifs_tests::fuzz::roundtrip(data));
