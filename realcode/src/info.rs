//! The model-info struct of a DLL, built from the FMU's own variable declarations (`fmi_export::Model::declare`): every input, output and parameter with its unit, width, default, minimum and maximum, and the C layout of the host's structs.

use crate::ffi::{self, DataType};
use fmi_export::describe::{declare, Config};
use fmi_export::model_description::{Causality, Variability};
use fmi_export::{Model, Value};
use std::ffi::CString;

/// What a DLL adds to its model's declarations.
#[derive(Debug, Clone, Copy)]
pub struct DllSpec {
    /// `FixedStepBaseSampleTime` (s): the host calls `Model_Outputs` every this long.
    pub step: f64,
    /// EMT = 1, RMS = 2, both = 3.
    pub emt_rms_mode: u8,
    /// `NumIntStates`: the words of the state blob (the running state, serialized).
    pub state_words: usize,
    /// The parameter that states the step the model assumes (it must equal `step`), if any.
    pub step_parameter: Option<&'static str>,
    /// The `[model]` table of the FMU's `config.toml` the DLL is built for (empty: defaults).
    pub config: &'static str,
}

/// How a variable is passed in the host's structs: Real as `real64_T`, Integer and Boolean as
/// `int32_T` (a Boolean 0 or 1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    Real,
    Integer,
    Boolean,
}

impl Kind {
    pub fn data_type(self) -> DataType {
        match self {
            Kind::Real => ffi::REAL64,
            Kind::Integer | Kind::Boolean => ffi::INT32,
        }
    }
}

/// One field of the host's inputs, outputs or parameters struct.
#[derive(Debug, Clone)]
pub struct Field {
    /// Its C name: the FMU name with every character outside `[A-Za-z0-9_]` as `_`
    /// (`adpf.p.lpf[1].tau` -> `adpf_p_lpf_1_tau`).
    pub name: String,
    /// The FMU's name of the variable.
    pub fmu_name: String,
    pub kind: Kind,
    /// Value reference in the FMU's store (per base type).
    pub vr: u32,
    /// Byte offset in the host's struct.
    pub offset: usize,
    pub unit: String,
    pub description: String,
    /// Start value (parameters: the default), and the accepted range.
    pub start: f64,
    pub min: f64,
    pub max: f64,
    /// A parameter a host may change between steps (`FixedValue` 0).
    pub tunable: bool,
}

/// The C name of an FMU variable name.
pub fn c_name(fmu_name: &str) -> String {
    let mut out = String::with_capacity(fmu_name.len());
    for ch in fmu_name.chars() {
        let ch = if ch.is_ascii_alphanumeric() { ch } else { '_' };
        if !(ch == '_' && out.ends_with('_')) {
            out.push(ch);
        }
    }
    let out = out.trim_end_matches('_').to_string();
    if out.starts_with(|c: char| c.is_ascii_digit()) {
        format!("_{out}")
    } else {
        out
    }
}

/// The fields of one struct and its size.
#[derive(Debug, Clone, Default)]
pub struct Group {
    pub fields: Vec<Field>,
    pub size: usize,
}

impl Group {
    fn laid_out(mut fields: Vec<Field>) -> Group {
        let (offsets, size) = ffi::c_layout(fields.iter().map(|f| (f.kind.data_type(), 1)));
        for (f, at) in fields.iter_mut().zip(offsets) {
            f.offset = at;
        }
        Group { fields, size }
    }

    pub fn find(&self, name: &str) -> Option<&Field> {
        self.fields
            .iter()
            .find(|f| f.name == name || f.fmu_name == name)
    }
}

/// A DLL's signals and parameters, from its model's declarations.
#[derive(Debug, Clone)]
pub struct Layout {
    pub identifier: &'static str,
    pub name: &'static str,
    pub description: &'static str,
    pub spec: DllSpec,
    pub inputs: Group,
    pub outputs: Group,
    pub parameters: Group,
    /// A digest of the layout (names, kinds, order), written beside the state so that the
    /// arrays of another model or version are refused.
    pub digest: u32,
}

impl Layout {
    /// The layout of model `M` for `spec`: every input, output and parameter of its
    /// declarations, in declaration order.
    pub fn of<M: Model>(spec: &DllSpec) -> Result<Layout, String> {
        let (_, vars) = declared::<M>(spec)?;
        let (mut inputs, mut outputs, mut parameters) = (Vec::new(), Vec::new(), Vec::new());
        for d in vars.declared() {
            let s = &d.spec;
            let (kind, start) = match &s.start {
                Value::Real(x) => (Kind::Real, *x),
                Value::Integer(k) => (Kind::Integer, f64::from(*k)),
                Value::Boolean(b) => (Kind::Boolean, if *b { 1.0 } else { 0.0 }),
                Value::String(_) => {
                    return Err(format!(
                        "'{}' is a String variable, which the DLL interface's structs do not carry",
                        s.name
                    ))
                }
            };
            let (min, max) = match kind {
                Kind::Boolean => (0.0, 1.0),
                Kind::Integer => {
                    let (lo, hi) = s.accepted_range();
                    (lo.max(f64::from(i32::MIN)), hi.min(f64::from(i32::MAX)))
                }
                Kind::Real => s.accepted_range(),
            };
            let field = Field {
                name: c_name(&s.name),
                fmu_name: s.name.clone(),
                kind,
                vr: d.vr,
                offset: 0,
                unit: s.unit.clone().unwrap_or_default(),
                description: s.description.clone(),
                start,
                min,
                max,
                tunable: s.variability == Variability::Tunable,
            };
            match s.causality {
                Causality::Input => inputs.push(field),
                Causality::Output => outputs.push(field),
                Causality::Parameter => parameters.push(field),
                _ => {}
            }
        }
        let mut names = std::collections::BTreeSet::new();
        for f in inputs.iter().chain(&outputs).chain(&parameters) {
            if !names.insert(f.name.clone()) {
                return Err(format!(
                    "two variables have the C name '{}' ('{}' is one)",
                    f.name, f.fmu_name
                ));
            }
        }
        let mut digest = 0x811c_9dc5u32;
        for f in inputs.iter().chain(&outputs).chain(&parameters) {
            for b in f.name.bytes().chain([f.kind as u8, 0]) {
                digest = (digest ^ u32::from(b)).wrapping_mul(0x0100_0193);
            }
        }
        Ok(Layout {
            identifier: M::IDENTIFIER,
            name: M::NAME,
            description: M::DESCRIPTION,
            spec: *spec,
            inputs: Group::laid_out(inputs),
            outputs: Group::laid_out(outputs),
            parameters: Group::laid_out(parameters),
            digest,
        })
    }
}

/// The model's declarations for the DLL's configuration (as the FMU with that `config.toml`).
pub fn declared<M: Model>(spec: &DllSpec) -> Result<(M, fmi_export::Variables), String> {
    let config: Config<M::Config> = if spec.config.is_empty() {
        Config::default()
    } else {
        toml::from_str(spec.config).map_err(|e| format!("the DLL's configuration: {e}"))?
    };
    declare::<M>(&config, None)
}

/// The model-info struct and the strings and arrays it points to (built once, read-only).
pub struct Info {
    pub layout: Layout,
    _strings: Vec<CString>,
    _inputs: Vec<ffi::Signal>,
    _outputs: Vec<ffi::Signal>,
    _parameters: Vec<ffi::Parameter>,
    pub info: ffi::ModelInfo,
}

// SAFETY: every pointer in `info` and the arrays points into the strings and vectors this
// value owns, which are never changed after `Info::build`; it is read-only from then on.
unsafe impl Sync for Info {}
// SAFETY: as above: moving the owner moves no heap data the pointers refer to.
unsafe impl Send for Info {}

impl Info {
    /// The info of model `M` for `spec`.
    pub fn build<M: Model>(spec: &DllSpec) -> Result<Info, String> {
        let layout = Layout::of::<M>(spec)?;
        let mut strings = Vec::new();
        let mut text = |s: &str| {
            let c = CString::new(s.replace('\0', " ")).expect("NUL bytes were replaced");
            let p = c.as_ptr();
            strings.push(c);
            p
        };
        let signal =
            |f: &Field, text: &mut dyn FnMut(&str) -> *const std::ffi::c_char| ffi::Signal {
                name: text(&f.name),
                description: text(&described(f)),
                unit: text(&f.unit),
                data_type: f.kind.data_type(),
                width: 1,
            };
        let inputs: Vec<ffi::Signal> = layout
            .inputs
            .fields
            .iter()
            .map(|f| signal(f, &mut text))
            .collect();
        let outputs: Vec<ffi::Signal> = layout
            .outputs
            .fields
            .iter()
            .map(|f| signal(f, &mut text))
            .collect();
        let parameters: Vec<ffi::Parameter> = layout
            .parameters
            .fields
            .iter()
            .map(|f| {
                let group = f.fmu_name.split('.').next().unwrap_or("").to_string();
                let (default_value, min_value, max_value) = match f.kind {
                    Kind::Real => (
                        ffi::DefaultValue {
                            real64_val: f.start,
                        },
                        ffi::MinMaxValue { real64_val: f.min },
                        ffi::MinMaxValue { real64_val: f.max },
                    ),
                    Kind::Integer | Kind::Boolean => (
                        ffi::DefaultValue {
                            int32_val: f.start as i32,
                        },
                        ffi::MinMaxValue {
                            int32_val: f.min as i32,
                        },
                        ffi::MinMaxValue {
                            int32_val: f.max as i32,
                        },
                    ),
                };
                ffi::Parameter {
                    name: text(&f.name),
                    group_name: text(&group),
                    description: text(&described(f)),
                    unit: text(&f.unit),
                    data_type: f.kind.data_type(),
                    fixed_value: i32::from(!f.tunable),
                    default_value,
                    min_value,
                    max_value,
                }
            })
            .collect();
        let general = format!(
            "Fixed step {} s (Model_Outputs once per step, inputs sampled at Time, outputs held over the next step). The same library object as the FMU {}.fmu; docs/realcode.md. Running state: {} int32 words (the serialized unit), no float or double states.",
            spec.step, layout.identifier, spec.state_words
        );
        let version = env!("CARGO_PKG_VERSION");
        let info = ffi::ModelInfo {
            dll_interface_version: ffi::INTERFACE_VERSION,
            model_name: text(layout.identifier),
            model_version: text(version),
            model_description: text(&format!("{}: {}", layout.name, layout.description)),
            general_information: text(&general),
            model_created: text("2026"),
            model_creator: text("dvpp project (dvpp-realcode)"),
            model_last_modified_date: text("2026"),
            model_last_modified_by: text("dvpp project"),
            model_modified_comment: text("generated from the FMU's variable declarations"),
            model_modified_history: text(version),
            fixed_step_base_sample_time: spec.step,
            emt_rms_mode: spec.emt_rms_mode,
            num_input_ports: inputs.len() as i32,
            input_ports_info: inputs.as_ptr(),
            num_output_ports: outputs.len() as i32,
            output_ports_info: outputs.as_ptr(),
            num_parameters: parameters.len() as i32,
            parameters_info: parameters.as_ptr(),
            num_int_states: spec.state_words as i32,
            num_float_states: 0,
            num_double_states: 0,
        };
        Ok(Info {
            layout,
            _strings: strings,
            _inputs: inputs,
            _outputs: outputs,
            _parameters: parameters,
            info,
        })
    }
}

/// A field's description with the FMU's name of it when that differs from the C name.
fn described(f: &Field) -> String {
    if f.fmu_name == f.name {
        f.description.clone()
    } else {
        format!("{} (FMU: {})", f.description, f.fmu_name)
    }
}

#[cfg(test)]
mod tests {
    use super::c_name;

    #[test]
    fn fmu_names_become_c_identifiers() {
        assert_eq!(c_name("adpf.p.lpf[1].tau"), "adpf_p_lpf_1_tau");
        assert_eq!(c_name("mu_p_lpf[8]"), "mu_p_lpf_8");
        assert_eq!(c_name("limit.current"), "limit_current");
        assert_eq!(c_name("Tdes.H"), "Tdes_H");
        assert_eq!(c_name("der[3].mu_p_lpf[2]"), "der_3_mu_p_lpf_2");
        assert_eq!(c_name("1x"), "_1x");
    }
}
