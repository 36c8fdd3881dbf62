//! What the examples share: taking their options out of the argument list (the rest are
//! images).

/// Removes `name VALUE` from `args` and returns `VALUE`, if the option is there.
pub fn take_option(args: &mut Vec<String>, name: &str) -> Option<String> {
    let i = args.iter().position(|a| a == name)?;
    let value = args
        .get(i + 1)
        .cloned()
        .unwrap_or_else(|| panic!("{name} takes a value"));
    args.drain(i..i + 2);
    Some(value)
}

/// Removes `--bpp R1,R2,...` from `args` and returns the rates, or `default` without it.
pub fn take_rates(args: &mut Vec<String>, default: &[f64]) -> Vec<f64> {
    take_option(args, "--bpp").map_or_else(
        || default.to_vec(),
        |list| {
            list.split(',')
                .map(|r| r.parse().expect("--bpp takes numbers"))
                .collect()
        },
    )
}
