//! The conveyor's model descriptions, written from its own declarations (the `FmuModel`
//! derive's variables, value references, start values, causalities): FMI 3.0's for the FMU
//! `fmi-export` exports, and FMI 2.0's for the FMI 2.0 C functions the FMU crate writes by hand,
//! with the same value references (0 is `time`). The packer (`conveyor-fmu-pack`) writes the
//! one of the archive it packs.

use fmi::schema::fmi3::{
    AbstractVariableTrait, Causality, Fmi3CoSimulation, Fmi3ModelDescription, Fmi3Unknown,
    InitializableVariableTrait, Variability, Variable, VariableDependency,
};
use fmi::schema::traits::FmiModelDescription;
use fmi_export::fmi3::Model;

use crate::Conveyor;

/// The FMI 3.0 `modelDescription.xml` of the conveyor (FMI 3.0 §2.4), from its declarations
/// (`FmuModel` derive), for the library `model_identifier` names (FMI 3.0 §2.5.1.1).
pub fn fmi3(model_identifier: &str) -> Result<String, String> {
    let mut meta = Conveyor::build_toplevel_metadata();
    // Every output is also an initial unknown (FMI 3.0 §2.4.8: outputs are calculated in
    // Initialization Mode), listed after the outputs as the schema orders them.
    let initial: Vec<VariableDependency> = meta
        .model_structure
        .unknowns
        .iter()
        .filter_map(|u| match u {
            VariableDependency::Output(o) => {
                Some(VariableDependency::InitialUnknown(Fmi3Unknown {
                    value_reference: o.value_reference,
                    ..Default::default()
                }))
            }
            _ => None,
        })
        .collect();
    meta.model_structure.unknowns.extend(initial);
    let md = Fmi3ModelDescription {
        fmi_version: "3.0".into(),
        model_name: Conveyor::MODEL_NAME.into(),
        instantiation_token: Conveyor::INSTANTIATION_TOKEN.into(),
        description: Some(
            "A belt conveyor: a mass on an elastic belt with viscous and Coulomb friction, \
             driven by a motor shaft, with a light barrier"
                .into(),
        ),
        generation_tool: Some("drivetwin conveyor-fmu (fmi-export)".into()),
        co_simulation: Some(Fmi3CoSimulation {
            model_identifier: model_identifier.into(),
            can_handle_variable_communication_step_size: Some(true),
            ..Default::default()
        }),
        model_variables: meta.model_variables,
        model_structure: meta.model_structure,
        ..Default::default()
    };
    md.serialize()
        .map_err(|e| format!("model description: {e}"))
}

/// The FMI 2.0 `modelDescription.xml` of the conveyor (FMI 2.0 §2.2), from the declarations
/// [`fmi3`] writes its description from: Float64 variables become `Real`, Boolean ones `Boolean`;
/// every output is an initial unknown (`initial="calculated"`, FMI 2.0 §2.2.8).
pub fn fmi2(model_identifier: &str) -> String {
    let meta = Conveyor::build_toplevel_metadata();
    let mut vars = String::new();
    let mut outputs = Vec::new();
    let mut index = 0usize;
    for v in &meta.model_variables.variables {
        let (element, start) = match v {
            Variable::Float64(f) => (
                "Real",
                f.start().and_then(|s| s.first()).map(|s| format!("{s:?}")),
            ),
            Variable::Boolean(b) => (
                "Boolean",
                b.start().and_then(|s| s.first()).map(|s| s.to_string()),
            ),
            _ => continue,
        };
        let v: &dyn AbstractVariableTrait = match v {
            Variable::Float64(f) => f,
            Variable::Boolean(b) => b,
            _ => continue,
        };
        index += 1;
        let causality = match v.causality() {
            Causality::Parameter | Causality::StructuralParameter => "parameter",
            Causality::CalculatedParameter => "calculatedParameter",
            Causality::Input => "input",
            Causality::Output => "output",
            Causality::Independent => "independent",
            Causality::Local | Causality::Dependent => "local",
        };
        if causality == "output" {
            outputs.push(index);
        }
        let variability = match v.variability() {
            Variability::Constant => "constant",
            Variability::Fixed => "fixed",
            Variability::Tunable => "tunable",
            Variability::Discrete => "discrete",
            Variability::Continuous => "continuous",
        };
        let description = v
            .description()
            .map(|d| format!(" description=\"{}\"", escape(d)))
            .unwrap_or_default();
        // An independent variable and the outputs have no start value (FMI 2.0 §2.2.7).
        let start = match (causality, start) {
            ("independent" | "output", _) | (_, None) => String::new(),
            (_, Some(s)) => format!(" start=\"{s}\""),
        };
        vars.push_str(&format!(
            "    <ScalarVariable name=\"{}\" valueReference=\"{}\"{description} \
             causality=\"{causality}\" variability=\"{variability}\">\n      <{element}{start}/>\n    \
             </ScalarVariable>\n",
            escape(v.name()),
            v.value_reference(),
        ));
    }
    let unknowns: String = outputs
        .iter()
        .map(|i| format!("      <Unknown index=\"{i}\"/>\n"))
        .collect();
    format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n\
         <fmiModelDescription fmiVersion=\"2.0\" modelName=\"{name}\" guid=\"{guid}\" \
         description=\"A belt conveyor: a mass on an elastic belt with viscous and Coulomb \
         friction, driven by a motor shaft, with a light barrier\" \
         generationTool=\"drivetwin conveyor-fmu (FMI 2.0 by hand)\" \
         variableNamingConvention=\"flat\" numberOfEventIndicators=\"0\">\n  \
         <CoSimulation modelIdentifier=\"{model_identifier}\" \
         canHandleVariableCommunicationStepSize=\"true\" \
         canNotUseMemoryManagementFunctions=\"true\"/>\n  \
         <ModelVariables>\n{vars}  </ModelVariables>\n  \
         <ModelStructure>\n    <Outputs>\n{unknowns}    </Outputs>\n    \
         <InitialUnknowns>\n{unknowns}    </InitialUnknowns>\n  </ModelStructure>\n\
         </fmiModelDescription>\n",
        name = escape(Conveyor::MODEL_NAME),
        guid = escape(Conveyor::INSTANTIATION_TOKEN),
    )
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

// ---- FMI 2.0 §2.1: the common functions ----

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_fmi2_description_names_every_variable_with_its_value_reference() {
        let xml = fmi2("conveyor");
        assert!(xml.contains("fmiVersion=\"2.0\""), "{xml}");
        assert!(xml.contains("name=\"light_barrier\""), "{xml}");
        assert!(xml.contains("<Boolean/>"), "{xml}");
        assert!(xml.contains("name=\"mass\""), "{xml}");
    }
}
