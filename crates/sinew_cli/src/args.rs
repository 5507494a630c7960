//! Value parsers for command-line numbers: a NaN, an infinity or a value
//! out of range is refused by clap with the argument's name, never passed on.

/// A finite number ≥ 0.
pub fn non_negative(text: &str) -> Result<f32, String> {
    let value: f32 = text.parse().map_err(|e| format!("{e}"))?;
    if value.is_finite() && value >= 0.0 {
        Ok(value)
    } else {
        Err(format!("{value} is not a finite number ≥ 0"))
    }
}

/// A finite number > 0.
pub fn positive(text: &str) -> Result<f32, String> {
    let value = non_negative(text)?;
    if value > 0.0 {
        Ok(value)
    } else {
        Err("0 is not a number > 0".into())
    }
}

/// A number in `[0, 1]`.
pub fn unit_interval(text: &str) -> Result<f32, String> {
    let value = non_negative(text)?;
    if value <= 1.0 {
        Ok(value)
    } else {
        Err(format!("{value} is not in [0, 1]"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refuses_nan_infinity_and_out_of_range() {
        assert_eq!(non_negative("2.5"), Ok(2.5));
        assert_eq!(non_negative("0"), Ok(0.0));
        assert!(non_negative("NaN").is_err());
        assert!(non_negative("inf").is_err());
        assert!(non_negative("-1").is_err());
        assert!(non_negative("x").is_err());
        assert!(positive("0").is_err());
        assert_eq!(positive("1e-3"), Ok(1e-3));
        assert!(unit_interval("1.5").is_err());
        assert_eq!(unit_interval("0.8"), Ok(0.8));
    }
}
