//! Measurements in tag values: `12`, `12 m`, `12.5m`, `40'`, `12'6"`, `3 ft`, `150 cm`
//! (thesis §2.3 "Measurements"; the OSM wiki's Map_Features/Units).

const METRES_PER_FOOT: f64 = 0.3048;
const METRES_PER_INCH: f64 = 0.0254;

/// Parses a length in metres; `None` for anything that is not one (`tall`, `5;6`, `NaN`).
pub fn parse_length_m(value: &str) -> Option<f64> {
    let value = value.trim();
    if value.is_empty() {
        return None;
    }
    if let Some(feet_inches) = parse_feet_inches(value) {
        return Some(feet_inches);
    }
    let split = value
        .find(|c: char| !(c.is_ascii_digit() || c == '.' || c == '-' || c == '+' || c == ','))
        .unwrap_or(value.len());
    let (number, unit) = value.split_at(split);
    let number: f64 = number.replace(',', ".").parse().ok()?;
    if !number.is_finite() {
        return None;
    }
    let factor = match unit.trim() {
        "" | "m" | "meter" | "meters" | "metre" | "metres" => 1.0,
        "km" => 1000.0,
        "cm" => 0.01,
        "mm" => 0.001,
        "ft" | "feet" | "foot" => METRES_PER_FOOT,
        "in" | "inch" | "inches" => METRES_PER_INCH,
        "mi" => 1609.344,
        _ => return None,
    };
    Some(number * factor)
}

/// `40'`, `12'6"`, `12' 6"`.
fn parse_feet_inches(value: &str) -> Option<f64> {
    let (feet, rest) = value.split_once('\'')?;
    let feet: f64 = feet.trim().parse().ok()?;
    let rest = rest.trim();
    let inches: f64 = if rest.is_empty() {
        0.0
    } else {
        rest.strip_suffix('"')?.trim().parse().ok()?
    };
    let metres = feet * METRES_PER_FOOT + inches * METRES_PER_INCH;
    metres.is_finite().then_some(metres)
}

/// Parses a plain count such as `building:levels=4` or `lanes=2`; `None` for non-numbers.
pub fn parse_count(value: &str) -> Option<f64> {
    let number: f64 = value.trim().replace(',', ".").parse().ok()?;
    number.is_finite().then_some(number)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_the_usual_spellings() {
        assert_eq!(parse_length_m("12"), Some(12.0));
        assert_eq!(parse_length_m("12 m"), Some(12.0));
        assert_eq!(parse_length_m("12.5m"), Some(12.5));
        assert_eq!(parse_length_m("3,5"), Some(3.5));
        assert!((parse_length_m("40'").unwrap() - 12.192).abs() < 1e-9);
        assert!((parse_length_m("12'6\"").unwrap() - 3.81).abs() < 1e-9);
        assert!((parse_length_m("10 ft").unwrap() - 3.048).abs() < 1e-9);
        assert_eq!(parse_length_m("150 cm"), Some(1.5));
    }

    #[test]
    fn rejects_what_is_not_a_length() {
        for bad in ["tall", "", "5;6", "NaN", "inf", "12 parsecs", "'"] {
            assert_eq!(parse_length_m(bad), None, "{bad}");
        }
        assert_eq!(parse_count("four"), None);
        assert_eq!(parse_count("4"), Some(4.0));
    }
}
