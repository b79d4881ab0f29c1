//! The case studies and the scenario compiler, as a library and the `dvpp-study` binary: the
//! scenario compiler turns `studies/scenarios/*.toml` into SSP systems (`cargo xtask bundle`
//! runs it); the case-study runners (the demo, case studies II and III) run the bundled systems
//! in the master and write CSVs, figures and the tables of `docs/case-studies.md`.

pub mod case3;
pub mod demo;
pub mod docs;
pub mod outage;
pub mod parallel;
pub mod qualify;
pub mod ride_through;
pub mod scenario;
pub mod sweep;

/// Check that `columns` has `<unit>.<port>` for exactly the units `expected` (each once, no
/// other), and return them in the order of `expected` (the grid's slot order): a renamed port or
/// a unit without it is an error naming what is missing, never an empty list.
pub fn units_with(
    columns: &[String],
    port: &str,
    expected: &[String],
) -> Result<Vec<String>, String> {
    let suffix = format!(".{port}");
    let found: Vec<String> = columns
        .iter()
        .filter_map(|c| c.strip_suffix(suffix.as_str()))
        .map(str::to_owned)
        .collect();
    let missing: Vec<&String> = expected.iter().filter(|u| !found.contains(u)).collect();
    let extra: Vec<&String> = found.iter().filter(|u| !expected.contains(u)).collect();
    if expected.is_empty() {
        return Err(format!(
            "no units expected with a column '*{suffix}': the system has no DER"
        ));
    }
    if !missing.is_empty() || !extra.is_empty() || found.len() != expected.len() {
        return Err(format!(
            "the columns '<unit>{suffix}' do not match the {} DER units: missing {missing:?}, unexpected {extra:?} (found {})",
            expected.len(),
            found.len()
        ));
    }
    Ok(expected.to_vec())
}

#[cfg(test)]
mod tests {
    use super::units_with;

    #[test]
    fn units_with_fails_on_a_renamed_port_or_a_missing_unit() {
        let units: Vec<String> = ["wind", "pv"].map(String::from).to_vec();
        let columns: Vec<String> = ["time", "wind.i_ac", "pv.i_ac", "pv.v_dc"]
            .map(String::from)
            .to_vec();
        assert_eq!(units_with(&columns, "i_ac", &units), Ok(units.clone()));
        let renamed = units_with(&columns, "i_ac_pu", &units).unwrap_err();
        assert!(renamed.contains("missing [\"wind\", \"pv\"]"), "{renamed}");
        let missing = units_with(&columns, "v_dc", &units).unwrap_err();
        assert!(missing.contains("missing [\"wind\"]"), "{missing}");
        assert!(units_with(&columns, "i_ac", &[]).is_err());
    }
}
