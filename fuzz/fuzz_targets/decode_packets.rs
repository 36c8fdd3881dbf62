//! Fuzz target: see `pifs_tests::fuzz::decode_packets`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| pifs_tests::fuzz::decode_packets(data));
