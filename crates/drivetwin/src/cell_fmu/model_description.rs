//! `modelDescription.xml` of a cell FMU (FMI 3.0 §2.4): the co-simulation interface, the units
//! of the variables, the variables of [`super::variables`] and the model structure (every
//! output is an output and an initial unknown, depending on every input), and the variables
//! of each bus's FMI-LS-BUS CAN terminal ([`super::can_terminal`]).

use std::fmt::Write;

use super::can_terminal::{self, Member};
use super::ls_bus;
use super::parameters::Parameters;
use super::variables::{Type, Variables};
use super::{INSTANTIATION_TOKEN, MODEL_IDENTIFIER};

/// The units the variables name, with their SI base units (FMI 3.0 §2.4.3).
const UNITS: &[(&str, &str)] = &[
    ("N.m", r#"kg="1" m="2" s="-2""#),
    ("rad", r#"rad="1""#),
    ("rad/s", r#"rad="1" s="-1""#),
    ("A", r#"A="1""#),
];

/// The description of a cell named `name` with `variables` and `buses` CAN buses (each with
/// its LS-BUS terminal).
pub fn model_description(name: &str, variables: &Variables, buses: usize) -> String {
    model_description_with(name, variables, buses, &Parameters::default())
}

/// [`model_description`] with the cell file's keys that are FMI parameters.
pub fn model_description_with(
    name: &str,
    variables: &Variables,
    buses: usize,
    parameters: &Parameters,
) -> String {
    let mut x = String::new();
    let _ = writeln!(x, r#"<?xml version="1.0" encoding="UTF-8"?>"#);
    let _ = writeln!(
        x,
        r#"<fmiModelDescription fmiVersion="3.0" modelName="{}" instantiationToken="{}" description="a drivetwin cell on its virtual clock" generationTool="drivetwin {}" variableNamingConvention="structured">"#,
        escape(name),
        escape(INSTANTIATION_TOKEN),
        env!("CARGO_PKG_VERSION")
    );
    let _ = writeln!(
        x,
        r#"  <CoSimulation modelIdentifier="{MODEL_IDENTIFIER}" canHandleVariableCommunicationStepSize="true" canGetAndSetFMUState="false" canSerializeFMUState="false" hasEventMode="true" providesIntermediateUpdate="false" canReturnEarlyAfterIntermediateUpdate="false"/>"#
    );
    x.push_str("  <UnitDefinitions>\n");
    for (unit, base) in UNITS {
        let _ = writeln!(
            x,
            r#"    <Unit name="{}"><BaseUnit {base}/></Unit>"#,
            escape(unit)
        );
    }
    for (unit, base) in parameters.units() {
        if UNITS.iter().all(|(u, _)| *u != unit) {
            let _ = writeln!(
                x,
                r#"    <Unit name="{}"><BaseUnit {base}/></Unit>"#,
                escape(unit)
            );
        }
    }
    x.push_str("  </UnitDefinitions>\n");
    x.push_str(r#"  <DefaultExperiment startTime="0" stepSize="0.001"/>"#);
    x.push('\n');
    x.push_str("  <ModelVariables>\n");
    x.push_str(r#"    <Float64 name="time" valueReference="0" causality="independent" variability="continuous" description="the cell's virtual clock, s"/>"#);
    x.push('\n');
    for v in variables.all() {
        let role = v.role;
        let (element, variability, start) = match (role.data_type(), role.is_input()) {
            (Type::Float64, true) => ("Float64", "continuous", Some("0")),
            (Type::Float64, false) => ("Float64", "continuous", None),
            (Type::Boolean, _) => ("Boolean", "discrete", Some("false")),
            (Type::UInt8, _) => ("UInt8", "discrete", None),
            (Type::UInt16, _) => ("UInt16", "discrete", None),
            (Type::Int32, _) => ("Int32", "discrete", None),
            (Type::String, _) => ("String", "discrete", None),
        };
        let causality = if role.is_input() { "input" } else { "output" };
        let _ = write!(
            x,
            r#"    <{element} name="{}" valueReference="{}" causality="{causality}" variability="{variability}" description="{}""#,
            escape(&v.name()),
            v.value_reference,
            escape(&role.description())
        );
        if let Some(unit) = role.unit() {
            let _ = write!(x, r#" unit="{}""#, escape(unit));
        }
        if let Some(start) = start {
            let _ = write!(x, r#" start="{start}""#);
        }
        x.push_str("/>\n");
    }
    terminal_variables(&mut x, buses);
    parameters.write_variables(&mut x);
    x.push_str("  </ModelVariables>\n");
    x.push_str("  <ModelStructure>\n");
    let outputs: Vec<u32> = variables
        .all()
        .filter(|v| !v.role.is_input())
        .map(|v| v.value_reference)
        .collect();
    for vr in &outputs {
        let _ = writeln!(x, r#"    <Output valueReference="{vr}"/>"#);
    }
    for b in 0..buses {
        for m in [Member::TxData, Member::TxClock] {
            let vr = can_terminal::value_reference(b, m);
            let _ = writeln!(x, r#"    <Output valueReference="{vr}"/>"#);
        }
    }
    for vr in &outputs {
        let _ = writeln!(x, r#"    <InitialUnknown valueReference="{vr}"/>"#);
    }
    // A clocked variable (Tx_Data) is no initial unknown; an output Clock is one (FMI 3.0
    // §2.4.8: an output with `initial` calculated, the default, and no `clocks`).
    for b in 0..buses {
        let vr = can_terminal::value_reference(b, Member::TxClock);
        let _ = writeln!(x, r#"    <InitialUnknown valueReference="{vr}"/>"#);
    }
    x.push_str("  </ModelStructure>\n");
    x.push_str("</fmiModelDescription>\n");
    x
}

/// Each bus's terminal (FMI-LS-BUS 1.0 §4.2): `Rx_Clock` a triggered input Clock, `Rx_Data`
/// a Binary input clocked by it, `Tx_Clock` a triggered output Clock, `Tx_Data` a Binary output
/// clocked by it; the Binary variables carry the CAN MIME type (§4.2.5).
fn terminal_variables(x: &mut String, buses: usize) {
    let mime = escape(ls_bus::MIME_TYPE);
    if buses > 0 {
        // §4.4.1.3: mandatory for a Network FMU, false (fire-and-forget) by default.
        let _ = writeln!(
            x,
            r#"    <Boolean name="{}" valueReference="{}" causality="structuralParameter" variability="fixed" start="false" description="the master takes Confirm and Bus Error for its frames"/>"#,
            can_terminal::BUS_NOTIFICATIONS,
            can_terminal::BUS_NOTIFICATIONS_VALUE_REFERENCE
        );
    }
    for b in 0..buses {
        let name = can_terminal::terminal_name(b);
        let vr = |m| can_terminal::value_reference(b, m);
        let _ = writeln!(
            x,
            r#"    <Clock name="{name}.Rx_Clock" valueReference="{}" causality="input" variability="discrete" intervalVariability="triggered" description="ticks when Rx_Data holds bus operations for the cell"/>"#,
            vr(Member::RxClock)
        );
        let _ = writeln!(
            x,
            r#"    <Binary name="{name}.Rx_Data" valueReference="{}" causality="input" variability="discrete" mimeType="{mime}" clocks="{}" description="FMI-LS-BUS CAN operations to the cell's bus {b}"><Start value=""/></Binary>"#,
            vr(Member::RxData),
            vr(Member::RxClock)
        );
        let _ = writeln!(
            x,
            r#"    <Clock name="{name}.Tx_Clock" valueReference="{}" causality="output" variability="discrete" intervalVariability="triggered" description="ticks at the end of a step in which frames crossed bus {b}"/>"#,
            vr(Member::TxClock)
        );
        let _ = writeln!(
            x,
            r#"    <Binary name="{name}.Tx_Data" valueReference="{}" causality="output" variability="discrete" mimeType="{mime}" clocks="{}" description="FMI-LS-BUS CAN operations from the cell's bus {b}"/>"#,
            vr(Member::TxData),
            vr(Member::TxClock)
        );
    }
}

/// Text as an XML attribute value.
fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c => out.push(c),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_description_parses_and_names_every_variable_once() {
        let vars = Variables::new(vec![1, 2]).unwrap();
        let xml = model_description("a <cell> & \"more\"", &vars, 0);
        let doc = roxmltree::Document::parse(&xml).unwrap();
        let root = doc.root_element();
        assert_eq!(root.attribute("fmiVersion"), Some("3.0"));
        assert_eq!(root.attribute("modelName"), Some("a <cell> & \"more\""));
        let names: Vec<&str> = doc
            .descendants()
            .filter(|n| n.has_attribute("causality"))
            .filter_map(|n| n.attribute("name"))
            .collect();
        assert_eq!(names.len(), 1 + vars.all().count());
        assert!(names.contains(&"node2.statusword"));
        let outputs = doc
            .descendants()
            .filter(|n| n.has_tag_name("Output"))
            .count();
        assert_eq!(outputs, 2 * 6);
    }

    #[test]
    fn each_bus_has_a_terminal_whose_data_is_clocked_by_its_clock() {
        let vars = Variables::new(vec![1]).unwrap();
        let xml = model_description("cell", &vars, 2);
        let doc = roxmltree::Document::parse(&xml).unwrap();
        let by_name = |n: &str| {
            doc.descendants()
                .find(|v| v.attribute("name") == Some(n))
                .unwrap()
        };
        for b in 0..2 {
            let rx = by_name(&format!("can{b}.Rx_Data"));
            let rx_clock = by_name(&format!("can{b}.Rx_Clock"));
            let tx = by_name(&format!("can{b}.Tx_Data"));
            let tx_clock = by_name(&format!("can{b}.Tx_Clock"));
            assert_eq!(rx.attribute("clocks"), rx_clock.attribute("valueReference"));
            assert_eq!(tx.attribute("clocks"), tx_clock.attribute("valueReference"));
            assert_eq!(rx.attribute("causality"), Some("input"));
            assert_eq!(tx.attribute("causality"), Some("output"));
            assert_eq!(rx_clock.attribute("intervalVariability"), Some("triggered"));
            assert_eq!(tx_clock.attribute("intervalVariability"), Some("triggered"));
            assert_eq!(rx.attribute("mimeType"), Some(ls_bus::MIME_TYPE));
        }
        let co = doc
            .descendants()
            .find(|n| n.has_tag_name("CoSimulation"))
            .unwrap();
        assert_eq!(co.attribute("hasEventMode"), Some("true"));
    }
}
