//! Blocks in the mission files: `.plan` survey and corridor complex items read from their
//! generated items and written back, TOML blocks, `.waypoints` refusing them, the one
//! validation of blocks and convert's block-by-block comparison.

use std::path::Path;

use serde_json::{json, Value};

use super::blocks::BlockKind;
use super::convert::{convert, losses};
use super::{load, load_str, to_string, Format, Mission};

fn shipped(file: &str) -> Mission {
    load(
        &Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("missions")
            .join(file),
    )
    .unwrap()
}

fn plan(items: Vec<Value>) -> String {
    json!({
        "fileType": "Plan",
        "version": 1,
        "mission": {
            "version": 2,
            "plannedHomePosition": [38.5, -121.7, 16.0],
            "items": items,
        },
    })
    .to_string()
}

fn item(command: u64, frame: u64, params: [Value; 7]) -> Value {
    json!({"type": "SimpleItem", "command": command, "frame": frame, "params": params,
           "autoContinue": true, "doJumpId": 0})
}

fn takeoff() -> Value {
    item(
        22,
        3,
        [
            json!(0),
            json!(0),
            json!(0),
            Value::Null,
            json!(38.5),
            json!(-121.7),
            json!(20),
        ],
    )
}

fn wp(north_deg: f64, alt: f64) -> Value {
    item(
        16,
        3,
        [
            json!(0),
            json!(0),
            json!(0),
            Value::Null,
            json!(38.5 + north_deg),
            json!(-121.7),
            json!(alt),
        ],
    )
}

fn command(id: u64, params: [f64; 7]) -> Value {
    item(id, 2, params.map(|p| json!(p)))
}

fn complex(kind: &str, version: u64, generated: Vec<Value>) -> Value {
    json!({
        "type": "ComplexItem",
        "complexItemType": kind,
        "version": version,
        "angle": 0,
        "polygon": [[38.5, -121.7], [38.501, -121.7], [38.501, -121.699]],
        "TransectStyleComplexItem": {"version": 2, "Items": generated, "TurnAroundDistance": 10},
    })
}

fn read(text: &str) -> Result<Mission, String> {
    load_str(text, Format::QgcPlan, Some(Path::new("t.plan"))).map_err(|e| e.to_string())
}

#[test]
fn the_shipped_orchard_survey_reads_as_two_survey_blocks_with_their_trigger_inside() {
    let m = shipped("orchard-survey.plan");
    assert_eq!(m.blocks.len(), 2);
    let names: Vec<&str> = m.blocks.iter().map(|b| b.name.as_str()).collect();
    assert_eq!(names, ["survey 1", "survey 2"]);
    for b in &m.blocks {
        assert_eq!(b.kind, BlockKind::Survey);
        assert!(b.reversible && b.len >= 16, "{}: {}", b.name, b.len);
        let first = &m.waypoints[b.first];
        let last = &m.waypoints[b.first + b.len - 1];
        // DO_SET_CAM_TRIGG_DIST on after the entry, off after the exit, nothing else.
        assert_eq!(first.actions.len(), 1);
        assert_eq!(first.actions[0].command, 206);
        assert!(first.actions[0].params[0] > 5.0);
        assert_eq!(last.actions.len(), 1);
        assert_eq!(last.actions[0].params[0], 0.0);
        assert!(m.waypoints[b.waypoints()].iter().all(|w| w.hover_s == 0.0));
        let source = b.source.as_ref().unwrap();
        assert_eq!(source["complexItemType"], "survey");
    }
    // The points between and around them are not in a block.
    assert_eq!(m.block_of(0), None);
    assert_eq!(m.block_of(m.blocks[0].first + m.blocks[0].len), None);
    assert_eq!(
        m.waypoints.len() - m.blocks.iter().map(|b| b.len).sum::<usize>(),
        5
    );
}

#[test]
fn commands_a_complex_item_carries_before_its_first_waypoint_stay_in_its_block() {
    let speed = command(178, [1.0, 4.0, -1.0, 0.0, 0.0, 0.0, 0.0]);
    let text = plan(vec![
        takeoff(),
        wp(0.0005, 20.0),
        complex(
            "survey",
            5,
            vec![
                speed,
                wp(0.001, 30.0),
                command(206, [10.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0]),
                wp(0.0015, 30.0),
            ],
        ),
    ]);
    let m = read(&text).unwrap();
    assert_eq!(m.blocks.len(), 1);
    let b = &m.blocks[0];
    assert_eq!((b.first, b.len), (1, 2));
    assert!(
        m.waypoints[0].actions.is_empty(),
        "rode on the waypoint before"
    );
    let carried: Vec<u16> = m.waypoints[1].actions.iter().map(|c| c.command).collect();
    assert_eq!(carried, [178, 206]);
    assert_eq!(m.waypoints[1].name, "WP2");
}

#[test]
fn a_corridor_scan_is_a_reversible_block_and_a_structure_scan_or_another_item_is_refused() {
    let text = plan(vec![
        takeoff(),
        complex("CorridorScan", 3, vec![wp(0.001, 30.0), wp(0.002, 30.0)]),
    ]);
    let m = read(&text).unwrap();
    assert_eq!(m.blocks[0].kind, BlockKind::Corridor);
    assert_eq!(m.blocks[0].name, "corridor scan 1");
    assert!(m.blocks[0].reversible);
    let structure =
        json!({"type": "ComplexItem", "complexItemType": "StructureScan", "version": 3});
    let e = read(&plan(vec![takeoff(), structure])).unwrap_err();
    assert!(
        e.starts_with("t.plan: mission item 1: complex item \"StructureScan\" is not supported")
            && e.contains("stores no generated items"),
        "{e}"
    );
    let other = json!({"type": "ComplexItem", "complexItemType": "fw_landing", "version": 1});
    let e = read(&plan(vec![takeoff(), other])).unwrap_err();
    assert!(
        e.contains("mission item 1: complex item \"fw_landing\" is not supported"),
        "{e}"
    );
}

#[test]
fn errors_in_a_complex_items_generated_items_name_the_file_and_the_item() {
    let bad = json!({"type": "SimpleItem", "command": 16, "frame": 3, "params": [0, 0]});
    let e = read(&plan(vec![
        takeoff(),
        complex("survey", 5, vec![wp(0.001, 30.0), bad]),
    ]))
    .unwrap_err();
    assert!(
        e.starts_with(
            "t.plan: mission.items[1].TransectStyleComplexItem.Items[1]: field \"params\""
        ),
        "{e}"
    );
    let rtl = command(20, [0.0; 7]);
    let e = read(&plan(vec![
        takeoff(),
        complex("survey", 5, vec![wp(0.001, 30.0), wp(0.002, 30.0), rtl]),
    ]))
    .unwrap_err();
    assert!(
        e.contains(
            "mission.items[1].TransectStyleComplexItem.Items[2].command: 20 in a complex item"
        ),
        "{e}"
    );
    let mut old = complex("survey", 3, vec![]);
    old.as_object_mut()
        .unwrap()
        .remove("TransectStyleComplexItem");
    let e = read(&plan(vec![takeoff(), old])).unwrap_err();
    assert!(
        e.starts_with("t.plan: mission.items[1].TransectStyleComplexItem: missing"),
        "{e}"
    );
    let e = read(&plan(vec![takeoff(), complex("survey", 6, vec![])])).unwrap_err();
    assert!(
        e.contains("mission.items[1].version: 6 is not supported"),
        "{e}"
    );
    let e = read(&plan(vec![
        takeoff(),
        complex("survey", 5, vec![wp(0.001, 30.0)]),
    ]))
    .unwrap_err();
    assert!(
        e.starts_with("t.plan: mission item 1: block \"survey 1\": 1 waypoint(s)"),
        "{e}"
    );
}

#[test]
fn an_unchanged_block_is_written_back_exactly_and_a_moved_one_has_its_items_rewritten() {
    let m = shipped("orchard-survey.plan");
    let text = to_string(&m, Format::QgcPlan).unwrap();
    let doc: Value = serde_json::from_str(&text).unwrap();
    let written: Vec<&Value> = doc["mission"]["items"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|i| i["type"] == "ComplexItem")
        .collect();
    assert_eq!(written.len(), 2);
    for (w, b) in written.iter().zip(&m.blocks) {
        assert_eq!(*w, b.source.as_ref().unwrap());
    }
    let mut moved = m.clone();
    let k = moved.blocks[1].first + 3;
    moved.waypoints[k].position.x_east_m += 5.0;
    let text = to_string(&moved, Format::QgcPlan).unwrap();
    let back = read(&text).unwrap();
    assert_eq!(losses(&moved, &back), vec![]);
    assert!(losses(&m, &back)
        .iter()
        .any(|l| l.setting.contains(&m.waypoints[k].name)));
    assert_eq!(back.blocks[0].source, m.blocks[0].source);
    assert_ne!(back.blocks[1].source, m.blocks[1].source);
}

fn toml_mission(waypoints: &str, blocks: &str) -> String {
    format!(
        "name = \"t\"\n[origin]\nlat_deg = 38.5\nlon_deg = -121.7\nhome_alt_amsl_m = 16.0\n\
         height_above_home_m = 10.0\n{waypoints}{blocks}"
    )
}

fn toml_wp(name: &str, x: f64, block: Option<&str>) -> String {
    let block = block.map_or(String::new(), |b| format!("block = \"{b}\"\n"));
    format!("[[waypoints]]\nname = \"{name}\"\nx_m = {x}\ny_m = 0.0\nz_m = 10.0\n{block}")
}

fn read_toml(text: &str) -> Result<Mission, String> {
    load_str(text, Format::Toml, Some(Path::new("t.toml"))).map_err(|e| e.to_string())
}

#[test]
fn toml_blocks_are_runs_of_waypoints_naming_a_declared_block() {
    let wps = [
        toml_wp("A", 0.0, None),
        toml_wp("B", 10.0, Some("rows")),
        toml_wp("C", 20.0, Some("rows")),
        toml_wp("D", 30.0, Some("rows")),
        toml_wp("E", 40.0, None),
    ]
    .concat();
    let m = read_toml(&toml_mission(
        &wps,
        "[[blocks]]\nname = \"rows\"\nreversible = false\n",
    ))
    .unwrap();
    assert_eq!(m.blocks.len(), 1);
    let b = &m.blocks[0];
    assert_eq!(
        (b.name.as_str(), b.kind, b.first, b.len, b.reversible),
        ("rows", BlockKind::Listed, 1, 3, false)
    );
    assert!(b.source.is_none());
    // Written and read back, block by block.
    let text = to_string(&m, Format::Toml).unwrap();
    assert_eq!(losses(&m, &read_toml(&text).unwrap()), vec![]);
}

/// The line of the table header just above the first line holding `needle`.
fn header_line(text: &str, needle: &str) -> usize {
    text.lines().position(|l| l.contains(needle)).unwrap()
}

#[test]
fn toml_block_errors_name_the_line_and_the_block() {
    let declared = "[[blocks]]\nname = \"rows\"\nreversible = true\n";
    let apart = [
        toml_wp("A", 0.0, Some("rows")),
        toml_wp("B", 10.0, Some("rows")),
        toml_wp("C", 20.0, None),
        toml_wp("D", 30.0, Some("rows")),
    ]
    .concat();
    let text = toml_mission(&apart, declared);
    let e = read_toml(&text).unwrap_err();
    let at = header_line(&text, "name = \"D\"");
    assert!(
        e.starts_with(&format!(
            "t.toml: line {at}: waypoint \"D\": block \"rows\" is used again"
        )),
        "{e}"
    );
    let one = [toml_wp("A", 0.0, Some("rows")), toml_wp("B", 10.0, None)].concat();
    let text = toml_mission(&one, declared);
    let e = read_toml(&text).unwrap_err();
    let at = header_line(&text, "name = \"rows\"");
    assert!(
        e.starts_with(&format!("t.toml: line {at}: block \"rows\": 1 waypoint(s)")),
        "{e}"
    );
    let undeclared = [
        toml_wp("A", 0.0, Some("row")),
        toml_wp("B", 10.0, Some("row")),
    ]
    .concat();
    let text = toml_mission(&undeclared, declared);
    let e = read_toml(&text).unwrap_err();
    let at = header_line(&text, "name = \"A\"");
    assert!(
        e.starts_with(&format!(
            "t.toml: line {at}: waypoint \"A\": block \"row\" is not declared"
        )),
        "{e}"
    );
    let none = [toml_wp("A", 0.0, None), toml_wp("B", 10.0, None)].concat();
    let text = toml_mission(&none, declared);
    let e = read_toml(&text).unwrap_err();
    let at = header_line(&text, "name = \"rows\"");
    assert!(
        e.starts_with(&format!(
            "t.toml: line {at}: block \"rows\": no waypoint belongs to it"
        )),
        "{e}"
    );
    let two = [
        toml_wp("A", 0.0, Some("rows")),
        toml_wp("B", 10.0, Some("rows")),
    ]
    .concat();
    let e = read_toml(&toml_mission(&two, &format!("{declared}{declared}"))).unwrap_err();
    assert!(e.contains("block \"rows\": duplicate name"), "{e}");
    let bad = "[[blocks]]\nname = \"rows\"\nreversible = true\nqgc = \"{\"\n";
    let e = read_toml(&toml_mission(&two, bad)).unwrap_err();
    assert!(e.contains("block \"rows\": qgc is not valid JSON"), "{e}");
}

#[test]
fn a_block_line_across_an_exclusion_zone_is_refused_naming_the_block_the_line_and_the_zone() {
    let at = |name: &str, x: f64, block: &str| {
        format!("[[waypoints]]\nname = \"{name}\"\nx_m = {x}\ny_m = 25.0\nz_m = 10.0\n{block}")
    };
    let fence = "[[fence.polygons]]\ninclusion = false\n\
                 vertices_m = [[-5.0, 20.0], [5.0, 20.0], [5.0, 30.0], [-5.0, 30.0]]\n";
    let blocks = "[[blocks]]\nname = \"rows\"\nreversible = true\n";
    let wps = [
        at("A", -30.0, "block = \"rows\"\n"),
        at("B", 30.0, "block = \"rows\"\n"),
        at("C", 40.0, ""),
    ]
    .concat();
    let e = read_toml(&toml_mission(&wps, &format!("{fence}{blocks}"))).unwrap_err();
    assert!(
        e.contains(
            "block \"rows\": its line \"A\"-\"B\" crosses exclusion polygon 1 of the geofence"
        ),
        "{e}"
    );
    // Without the block, the same leg is the planner's to detour round.
    let free = wps.replace("block = \"rows\"\n", "");
    assert!(read_toml(&toml_mission(&free, fence)).is_ok());
}

#[test]
fn blocks_out_of_range_of_one_waypoint_or_overlapping_are_refused() {
    let m = shipped("paper-sample-8wp.toml");
    let raw = |first: usize, len: usize, name: &str| super::RawBlock {
        name: name.into(),
        kind: BlockKind::Listed,
        first,
        len,
        reversible: true,
        source: None,
        place: super::Place::Line(3),
    };
    let check = |blocks| {
        super::check_blocks("f", &m.origin, &m.fence, &m.waypoints, blocks)
            .map(|b| b.len())
            .map_err(|e| e.to_string())
    };
    assert_eq!(check(vec![raw(0, 2, "a"), raw(2, 3, "b")]), Ok(2));
    let e = check(vec![raw(6, 3, "a")]).unwrap_err();
    assert!(
        e.starts_with("f: line 3: block \"a\": waypoints 7..9 of a mission of 8"),
        "{e}"
    );
    let e = check(vec![raw(0, 1, "a")]).unwrap_err();
    assert!(e.contains("block \"a\": 1 waypoint(s)"), "{e}");
    let e = check(vec![raw(0, 3, "a"), raw(2, 2, "b")]).unwrap_err();
    assert!(
        e.contains("block \"b\": shares waypoints with block \"a\""),
        "{e}"
    );
}

#[test]
fn the_orchard_survey_round_trips_toml_and_plan_block_by_block_and_waypoints_lose_the_blocks() {
    let m = shipped("orchard-survey.plan");
    let (toml, lost) = convert(&m, Path::new("o.toml")).unwrap();
    assert_eq!(lost, vec![]);
    let there = read_toml(&toml).unwrap();
    let (plan, back) = convert(&there, Path::new("o.plan")).unwrap();
    assert_eq!(back, vec![]);
    assert_eq!(read(&plan).unwrap().blocks, m.blocks);
    // .waypoints: refused when written, a loss per block when converted.
    let e = to_string(&m, Format::Wpl).unwrap_err().to_string();
    assert!(
        e.contains("cannot hold block \"survey 1\" (survey, 24 waypoints), block \"survey 2\""),
        "{e}"
    );
    let (_, lost) = convert(&m, Path::new("o.waypoints")).unwrap();
    let blocks: Vec<String> = lost
        .iter()
        .filter(|l| l.setting.starts_with("block"))
        .map(|l| l.to_string())
        .collect();
    assert_eq!(blocks.len(), 2, "{blocks:?}");
    assert!(
        blocks[0]
            .starts_with("block \"survey 1\": survey of waypoints WP3-WP26, reversible -> none"),
        "{blocks:?}"
    );
}

#[test]
fn convert_names_a_block_that_differs() {
    let m = shipped("orchard-survey.plan");
    let mut other = m.clone();
    other.blocks[1].reversible = false;
    other.blocks[0].name = "north".into();
    let said: Vec<String> = losses(&m, &other).iter().map(|l| l.to_string()).collect();
    assert_eq!(said.len(), 2, "{said:?}");
    assert!(
        said[0].starts_with(
            "block \"survey 1\": survey of waypoints WP3-WP26, reversible -> \"north\""
        ),
        "{said:?}"
    );
    assert!(
        said[1].starts_with("block \"survey 2\": survey of waypoints")
            && said[1].ends_with("one way"),
        "{said:?}"
    );
    let mut settings = m.clone();
    if let Some(s) = settings.blocks[0].source.as_mut() {
        s["angle"] = json!(40);
    }
    let said: Vec<String> = losses(&m, &settings)
        .iter()
        .map(|l| l.to_string())
        .collect();
    assert_eq!(
        said,
        ["block \"survey 1\" complex item: its QGroundControl complex item -> changed settings"]
    );
}

#[test]
fn a_subset_keeps_what_remains_of_each_block_and_flies_a_lone_remnant_as_a_point() {
    let m = shipped("orchard-survey.plan");
    let (one, two) = (&m.blocks[0], &m.blocks[1]);
    // Resumed after the first waypoint of survey 1 (and the two points before it).
    let kept: Vec<usize> = (one.first + 1..m.waypoints.len()).collect();
    let rest = m.keeping(&kept);
    assert_eq!(rest.blocks.len(), 2);
    assert_eq!((rest.blocks[0].first, rest.blocks[0].len), (0, one.len - 1));
    assert_eq!(rest.blocks[1].first, two.first - one.first - 1);
    assert_eq!(rest.blocks[1].len, two.len);
    for b in &rest.blocks {
        assert_eq!(
            rest.waypoints[b.first].name,
            m.waypoints[kept[b.first]].name
        );
    }
    // Only the last waypoint of survey 1 left: it is a point.
    let kept: Vec<usize> = (one.first + one.len - 1..m.waypoints.len()).collect();
    let rest = m.keeping(&kept);
    assert_eq!(rest.blocks.len(), 1);
    assert_eq!(rest.blocks[0].name, "survey 2");
}
