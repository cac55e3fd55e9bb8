//! The documents say what the tool does: every section the README points to "below" or by name
//! (from its own text, a vehicle file or a document) is a section of the README, and the numbers
//! docs/mission-files.md quotes for the shipped missions are the tool's.

use std::path::Path;

use super::json;
use super::service::root;

/// The headings of a Markdown text, without their `#`s.
fn headings(text: &str) -> Vec<String> {
    (text.lines())
        .filter(|l| l.starts_with('#'))
        .map(|l| l.trim_start_matches('#').trim().to_string())
        .collect()
}

/// Every `"NAME"` in `text` that `near` says where to find: quoted right before ` below` or
/// right after `below, `, or (`README "NAME"`) after the README's name.
fn quoted_refs(text: &str) -> Vec<(String, String)> {
    let flat = text.split_whitespace().collect::<Vec<_>>().join(" ");
    let mut found = Vec::new();
    let quoted: Vec<&str> = flat.split('"').collect();
    // Odd pieces are inside quotes.
    for k in (1..quoted.len()).step_by(2) {
        let (before, name, after) = (quoted[k - 1], quoted[k], quoted.get(k + 1).unwrap_or(&""));
        let context = if after.starts_with(" below") || before.ends_with("below, ") {
            Some("below")
        } else if before.ends_with("README ") {
            Some("README")
        } else {
            None
        };
        if let Some(context) = context {
            found.push((context.to_string(), name.to_string()));
        }
    }
    found
}

fn files_under(dir: &Path, ext: &str, out: &mut Vec<std::path::PathBuf>) {
    for entry in std::fs::read_dir(dir).expect("readable").flatten() {
        let path = entry.path();
        if path.is_dir() {
            files_under(&path, ext, out);
        } else if path.extension().is_some_and(|e| e == ext) {
            out.push(path);
        }
    }
}

#[test]
fn every_readme_section_pointed_to_below_or_by_name_is_one() {
    let readme = std::fs::read_to_string(root().join("README.md")).expect("README.md");
    let sections = headings(&readme);
    let mut wrong = Vec::new();
    for (_, name) in quoted_refs(&readme) {
        if !sections.contains(&name) {
            wrong.push(format!("README.md: \"{name}\" is not a README section"));
        }
    }
    // "(below)" with no name: a section the README does not have under that phrase.
    if readme.contains("(below)") {
        wrong.push("README.md: \"(below)\" points to no section".into());
    }
    let mut others = Vec::new();
    files_under(&root().join("docs"), "md", &mut others);
    files_under(&root().join("models"), "toml", &mut others);
    for path in others {
        let text = std::fs::read_to_string(&path).expect("readable");
        for (context, name) in quoted_refs(&text) {
            if context == "README" && !sections.contains(&name) {
                wrong.push(format!(
                    "{}: README \"{name}\" is not a README section",
                    path.display()
                ));
            }
        }
    }
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
}

/// The number before `unit` in `text` after `from`, as written.
fn number_after<'a>(text: &'a str, from: &str, unit: &str) -> &'a str {
    let rest = &text[text.find(from).unwrap_or_else(|| panic!("{from}")) + from.len()..];
    rest[..rest.find(unit).unwrap_or_else(|| panic!("{unit}"))].trim()
}

#[test]
fn the_mission_files_doc_quotes_the_tools_own_numbers_for_the_shipped_missions() {
    let doc = std::fs::read_to_string(root().join("docs/mission-files.md")).expect("doc");
    let doc = doc.split_whitespace().collect::<Vec<_>>().join(" ");
    let split = json(&[
        "plan",
        "missions/long-inspection.toml",
        "--sorties",
        "--json",
    ]);
    let s = &split["sorties"];
    let one_decimal = |v: &serde_json::Value| format!("{:.1}", v.as_f64().expect("a number"));
    assert_eq!(
        number_after(&doc, "splits it (exact, ", " kJ vs"),
        one_decimal(&s["total_kj"])
    );
    assert_eq!(
        number_after(&doc, " kJ vs ", " kJ as one tour"),
        one_decimal(&s["single_tour_kj"])
    );
    let survey = json(&["plan", "missions/long-survey.toml", "--json"]);
    assert_eq!(
        number_after(&doc, "prices them composed (", " kJ for the legs"),
        one_decimal(&survey["battery"]["legs_kj"])
    );
}
