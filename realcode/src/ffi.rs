//! The C types of the IEEE/Cigré DLL interface for real-code models (CIGRE TB958, API version 2), laid out as this project's `include/IEEE_Cigre_DLLInterface.h` declares them.

use std::ffi::{c_char, c_void};

/// `IEEE_Cigre_DLLInterface_DataType`: a C enum (an `int`).
pub type DataType = i32;
pub const CHAR: DataType = 1;
pub const INT8: DataType = 2;
pub const UINT8: DataType = 3;
pub const INT16: DataType = 4;
pub const UINT16: DataType = 5;
pub const INT32: DataType = 6;
pub const UINT32: DataType = 7;
pub const REAL32: DataType = 8;
pub const REAL64: DataType = 9;
pub const C_STRING: DataType = 10;

/// Return values of the instance-taking functions.
pub const RETURN_OK: i32 = 0;
/// A message in `LastGeneralMessage`; the simulation continues.
pub const RETURN_MESSAGE: i32 = 1;
/// An error in `LastErrorMessage`; the host stops the simulation.
pub const RETURN_ERROR: i32 = 2;

/// `DLLInterfaceVersion` this project implements (API version 2 of the standard, whose
/// published header states 1.1.0.0).
pub const INTERFACE_VERSION: [u8; 4] = [1, 1, 0, 0];

/// `IEEE_Cigre_DLLInterface_Signal`: one input or output port.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct Signal {
    pub name: *const c_char,
    pub description: *const c_char,
    pub unit: *const c_char,
    pub data_type: DataType,
    pub width: i32,
}

/// `union DefaultValueU`.
#[repr(C)]
#[derive(Clone, Copy)]
pub union DefaultValue {
    pub char_val: c_char,
    pub char_ptr: *const c_char,
    pub int8_val: i8,
    pub uint8_val: u8,
    pub int16_val: i16,
    pub uint16_val: u16,
    pub int32_val: i32,
    pub uint32_val: u32,
    pub real32_val: f32,
    pub real64_val: f64,
}

/// `union MinMaxValueU`.
#[repr(C)]
#[derive(Clone, Copy)]
pub union MinMaxValue {
    pub char_val: c_char,
    pub int8_val: i8,
    pub uint8_val: u8,
    pub int16_val: i16,
    pub uint16_val: u16,
    pub int32_val: i32,
    pub uint32_val: u32,
    pub real32_val: f32,
    pub real64_val: f64,
}

/// `IEEE_Cigre_DLLInterface_Parameter`: one scalar parameter.
#[repr(C)]
#[derive(Clone, Copy)]
pub struct Parameter {
    pub name: *const c_char,
    pub group_name: *const c_char,
    pub description: *const c_char,
    pub unit: *const c_char,
    pub data_type: DataType,
    /// 0: may change at any time; 1: set before time 0 only.
    pub fixed_value: i32,
    pub default_value: DefaultValue,
    pub min_value: MinMaxValue,
    pub max_value: MinMaxValue,
}

/// `IEEE_Cigre_DLLInterface_Model_Info`: what `Model_GetInfo` returns.
#[repr(C)]
pub struct ModelInfo {
    pub dll_interface_version: [u8; 4],
    pub model_name: *const c_char,
    pub model_version: *const c_char,
    pub model_description: *const c_char,
    pub general_information: *const c_char,
    pub model_created: *const c_char,
    pub model_creator: *const c_char,
    pub model_last_modified_date: *const c_char,
    pub model_last_modified_by: *const c_char,
    pub model_modified_comment: *const c_char,
    pub model_modified_history: *const c_char,
    /// The model's fixed step (s).
    pub fixed_step_base_sample_time: f64,
    /// EMT = 1, RMS = 2, both = 3.
    pub emt_rms_mode: u8,
    pub num_input_ports: i32,
    pub input_ports_info: *const Signal,
    pub num_output_ports: i32,
    pub output_ports_info: *const Signal,
    pub num_parameters: i32,
    pub parameters_info: *const Parameter,
    pub num_int_states: i32,
    pub num_float_states: i32,
    pub num_double_states: i32,
}

/// `IEEE_Cigre_DLLInterface_Instance`: one instance, allocated by the host with every array
/// it points to.
#[repr(C)]
#[derive(Debug)]
pub struct Instance {
    pub external_inputs: *mut c_void,
    pub external_outputs: *mut c_void,
    pub parameters: *mut c_void,
    pub time: f64,
    pub sim_tool_emt_rms_mode: u8,
    pub last_error_message: *const c_char,
    pub last_general_message: *const c_char,
    pub int_states: *mut i32,
    pub float_states: *mut f32,
    pub double_states: *mut f64,
}

impl Instance {
    /// An instance attached to nothing yet, in EMT mode, as a host sets one up before it
    /// allocates the structs and state arrays.
    pub fn unattached() -> Instance {
        Instance {
            external_inputs: std::ptr::null_mut(),
            external_outputs: std::ptr::null_mut(),
            parameters: std::ptr::null_mut(),
            time: 0.0,
            sim_tool_emt_rms_mode: 1,
            last_error_message: std::ptr::null(),
            last_general_message: std::ptr::null(),
            int_states: std::ptr::null_mut(),
            float_states: std::ptr::null_mut(),
            double_states: std::ptr::null_mut(),
        }
    }
}

/// The byte size and alignment of a scalar of type `t` in the host's structs (none for a
/// string pointer, which this project does not use).
pub fn scalar_size(t: DataType) -> Option<usize> {
    match t {
        CHAR | INT8 | UINT8 => Some(1),
        INT16 | UINT16 => Some(2),
        INT32 | UINT32 | REAL32 => Some(4),
        REAL64 => Some(8),
        _ => None,
    }
}

/// The byte offsets of a C struct of the scalar fields `fields` (type, width) in order, each at
/// its natural alignment, and the struct's size (padded to its largest alignment): what an
/// import tool computes from the model info.
pub fn c_layout(fields: impl IntoIterator<Item = (DataType, i32)>) -> (Vec<usize>, usize) {
    let mut offsets = Vec::new();
    let (mut at, mut align) = (0usize, 1usize);
    for (t, width) in fields {
        let size = scalar_size(t).unwrap_or(8);
        at = at.next_multiple_of(size);
        offsets.push(at);
        at += size * width.max(1) as usize;
        align = align.max(size);
    }
    (offsets, at.next_multiple_of(align))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn c_layout_aligns_each_scalar_and_pads_the_struct() {
        // int32, real64, int32: 0, 8, 16; size 24 (padded to 8).
        assert_eq!(
            c_layout([(INT32, 1), (REAL64, 1), (INT32, 1)]),
            (vec![0, 8, 16], 24)
        );
        // Reals only: dense.
        assert_eq!(c_layout([(REAL64, 1), (REAL64, 1)]), (vec![0, 8], 16));
        // A width-3 uint8 array, then an int16: 0, 4; size 6.
        assert_eq!(c_layout([(UINT8, 3), (INT16, 1)]), (vec![0, 4], 6));
    }

    #[test]
    fn the_structs_have_the_standards_layout_on_64_bit_targets() {
        use std::mem::{offset_of, size_of};
        assert_eq!(size_of::<Signal>(), 32);
        assert_eq!(size_of::<Parameter>(), 64);
        assert_eq!(offset_of!(Parameter, default_value), 40);
        assert_eq!(offset_of!(ModelInfo, model_name), 8);
        assert_eq!(offset_of!(ModelInfo, fixed_step_base_sample_time), 88);
        assert_eq!(offset_of!(ModelInfo, emt_rms_mode), 96);
        assert_eq!(offset_of!(ModelInfo, input_ports_info), 104);
        assert_eq!(offset_of!(Instance, time), 24);
        assert_eq!(offset_of!(Instance, last_error_message), 40);
        assert_eq!(offset_of!(Instance, double_states), 72);
    }
}
