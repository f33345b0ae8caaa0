//! `modelDescription.xml` of a cell FMU (FMI 3.0 §2.4): the co-simulation interface, the units
//! of the variables, the variables of [`super::variables`] and the model structure (every
//! output is an output and an initial unknown, depending on every input).

use std::fmt::Write;

use super::variables::{Type, Variables};
use super::{INSTANTIATION_TOKEN, MODEL_IDENTIFIER};

/// The units the variables name, with their SI base units (FMI 3.0 §2.4.3).
const UNITS: &[(&str, &str)] = &[
    ("N.m", r#"kg="1" m="2" s="-2""#),
    ("rad", r#"rad="1""#),
    ("rad/s", r#"rad="1" s="-1""#),
    ("A", r#"A="1""#),
];

/// The description of a cell named `name` with `variables`.
pub fn model_description(name: &str, variables: &Variables) -> String {
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
        r#"  <CoSimulation modelIdentifier="{MODEL_IDENTIFIER}" canHandleVariableCommunicationStepSize="true" canGetAndSetFMUState="false" canSerializeFMUState="false" hasEventMode="false" providesIntermediateUpdate="false" canReturnEarlyAfterIntermediateUpdate="false"/>"#
    );
    x.push_str("  <UnitDefinitions>\n");
    for (unit, base) in UNITS {
        let _ = writeln!(
            x,
            r#"    <Unit name="{}"><BaseUnit {base}/></Unit>"#,
            escape(unit)
        );
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
    for vr in &outputs {
        let _ = writeln!(x, r#"    <InitialUnknown valueReference="{vr}"/>"#);
    }
    x.push_str("  </ModelStructure>\n");
    x.push_str("</fmiModelDescription>\n");
    x
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
        let xml = model_description("a <cell> & \"more\"", &vars);
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
}
