//! Names for a closed set of choices (a profile, a solver, a guard policy, a pricing), as typed on
//! the command line or written in a file: one lookup, and one error for a name not among them
//! that says what was given and what is allowed.

/// A name not among the choices.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown {what} {given:?} (allowed: {})", allowed.join(", "))]
pub struct UnknownName {
    /// What was being named ("profile", "solver", ...).
    pub what: &'static str,
    pub given: String,
    pub allowed: Vec<&'static str>,
}

/// The choice `given` names among `choices` (name, value), compared ignoring ASCII case.
pub fn choose<T: Copy>(
    what: &'static str,
    given: &str,
    choices: &[(&'static str, T)],
) -> Result<T, UnknownName> {
    choices
        .iter()
        .find(|(name, _)| name.eq_ignore_ascii_case(given))
        .map(|(_, value)| *value)
        .ok_or_else(|| UnknownName {
            what,
            given: given.to_string(),
            allowed: choices.iter().map(|(name, _)| *name).collect(),
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_name_is_found_in_any_case_and_an_unknown_one_is_refused_listing_the_choices() {
        let choices = [("warn", 1), ("rtl", 2)];
        assert_eq!(choose("guard policy", "RTL", &choices), Ok(2));
        let err = choose("guard policy", "home", &choices).unwrap_err();
        assert_eq!(
            err.to_string(),
            "unknown guard policy \"home\" (allowed: warn, rtl)"
        );
    }
}
