//! libFuzzer target: any bytes, read as text (invalid UTF-8 replaced), through the deck reader,
//! the builder and a few steps of simulation; the property is `tests/common/hostile.rs`.
#![no_main]

use libfuzzer_sys::fuzz_target;

#[path = "../../tests/common/hostile.rs"]
#[allow(
    dead_code,
    reason = "the proptest harness uses the outcome, this one does not"
)]
mod hostile;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    hostile::exercise(&text, 3);
});
