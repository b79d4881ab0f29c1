/*
 * IEEE_Cigre_DLLInterface.h -- the IEEE/Cigre DLL interface for real-code models
 * (CIGRE Technical Brochure 958, joint working group CIGRE B4.82 / IEEE; API version 2),
 * written for the dvpp project from the interface's published definitions: the order and
 * the C types of every struct member are the standard's, so that a DLL built against this
 * header loads in any host built against the standard's own header.
 *
 * A host (an EMT or RMS tool, or its import tool) calls Model_GetInfo to learn the model's
 * ports, parameters, fixed step and state sizes; allocates per instance the inputs, outputs
 * and parameters structs (C structs of the listed scalars in order, each at its natural
 * alignment) and the three state arrays; then calls Model_FirstCall, Model_CheckParameters,
 * Model_Initialize at time 0, Model_Outputs once per fixed step (and Model_Iterate in RMS
 * tools), and Model_Terminate at the end. Every instance-taking function returns 0 (fine),
 * 1 (a message in LastGeneralMessage) or 2 (an error in LastErrorMessage; stop).
 */
#ifndef IEEE_CIGRE_DLLINTERFACE_H
#define IEEE_CIGRE_DLLINTERFACE_H

#include <stdint.h>

typedef char char_T;
typedef int8_t int8_T;
typedef uint8_t uint8_T;
typedef int16_t int16_T;
typedef uint16_t uint16_T;
typedef int32_t int32_T;
typedef uint32_t uint32_T;
typedef float real32_T;
typedef double real64_T;

#ifdef _WIN32
#define IEEE_CIGRE_CALL __cdecl
#define IEEE_CIGRE_EXPORT __declspec(dllexport)
#else
#define IEEE_CIGRE_CALL
#define IEEE_CIGRE_EXPORT
#endif

/* The type of a port or parameter. */
enum IEEE_Cigre_DLLInterface_DataType {
    IEEE_Cigre_DLLInterface_DataType_char_T = 1,
    IEEE_Cigre_DLLInterface_DataType_int8_T = 2,
    IEEE_Cigre_DLLInterface_DataType_uint8_T = 3,
    IEEE_Cigre_DLLInterface_DataType_int16_T = 4,
    IEEE_Cigre_DLLInterface_DataType_uint16_T = 5,
    IEEE_Cigre_DLLInterface_DataType_int32_T = 6,
    IEEE_Cigre_DLLInterface_DataType_uint32_T = 7,
    IEEE_Cigre_DLLInterface_DataType_real32_T = 8,
    IEEE_Cigre_DLLInterface_DataType_real64_T = 9,
    IEEE_Cigre_DLLInterface_DataType_c_string_T = 10
};

/* What the instance-taking functions return. */
enum IEEE_Cigre_DLLInterface_Return_Value {
    IEEE_Cigre_DLLInterface_Return_OK = 0,
    IEEE_Cigre_DLLInterface_Return_Message = 1,
    IEEE_Cigre_DLLInterface_Return_Error = 2
};

/* One input or output port: a C identifier, a description, a unit, its type and width. */
typedef struct _IEEE_Cigre_DLLInterface_Signal {
    const char_T *const Name;
    const char_T *const Description;
    const char_T *const Unit;
    const enum IEEE_Cigre_DLLInterface_DataType DataType;
    const int32_T Width;
} IEEE_Cigre_DLLInterface_Signal;

/* A parameter's default; a string parameter's is Char_Ptr. */
union DefaultValueU {
    const char_T Char_Val;
    const char_T *const Char_Ptr;
    const int8_T Int8_Val;
    const uint8_T Uint8_Val;
    const int16_T Int16_Val;
    const uint16_T Uint16_Val;
    const int32_T Int32_Val;
    const uint32_T Uint32_Val;
    const real32_T Real32_Val;
    const real64_T Real64_Val;
};

/* A parameter's minimum or maximum. */
union MinMaxValueU {
    const char_T Char_Val;
    const int8_T Int8_Val;
    const uint8_T Uint8_Val;
    const int16_T Int16_Val;
    const uint16_T Uint16_Val;
    const int32_T Int32_Val;
    const uint32_T Uint32_Val;
    const real32_T Real32_Val;
    const real64_T Real64_Val;
};

/* One scalar parameter. FixedValue: 0 = may change during a run, 1 = set before time 0 only. */
typedef struct _IEEE_Cigre_DLLInterface_Parameter {
    const char_T *const Name;
    const char_T *const GroupName;
    const char_T *const Description;
    const char_T *const Unit;
    const enum IEEE_Cigre_DLLInterface_DataType DataType;
    const int32_T FixedValue;
    union DefaultValueU DefaultValue;
    union MinMaxValueU MinValue;
    union MinMaxValueU MaxValue;
} IEEE_Cigre_DLLInterface_Parameter;

/* The model's static description (Model_GetInfo). EMT_RMS_Mode: 1 EMT, 2 RMS, 3 both. */
typedef struct _IEEE_Cigre_DLLInterface_Model_Info {
    const uint8_T DLLInterfaceVersion[4];
    const char_T *const ModelName;
    const char_T *const ModelVersion;
    const char_T *const ModelDescription;
    const char_T *const GeneralInformation;
    const char_T *const ModelCreated;
    const char_T *const ModelCreator;
    const char_T *const ModelLastModifiedDate;
    const char_T *const ModelLastModifiedBy;
    const char_T *const ModelModifiedComment;
    const char_T *const ModelModifiedHistory;
    const real64_T FixedStepBaseSampleTime;
    const uint8_T EMT_RMS_Mode;
    const int32_T NumInputPorts;
    const IEEE_Cigre_DLLInterface_Signal *const InputPortsInfo;
    const int32_T NumOutputPorts;
    const IEEE_Cigre_DLLInterface_Signal *const OutputPortsInfo;
    const int32_T NumParameters;
    const IEEE_Cigre_DLLInterface_Parameter *const ParametersInfo;
    const int32_T NumIntStates;
    const int32_T NumFloatStates;
    const int32_T NumDoubleStates;
} IEEE_Cigre_DLLInterface_Model_Info;

/* One instance; the host allocates it and everything it points to. */
typedef struct _IEEE_Cigre_DLLInterface_Instance {
    void *ExternalInputs;
    void *ExternalOutputs;
    void *Parameters;
    real64_T Time;
    const uint8_T SimTool_EMT_RMS_Mode;
    const char_T *LastErrorMessage;
    const char_T *LastGeneralMessage;
    int32_T *IntStates;
    real32_T *FloatStates;
    real64_T *DoubleStates;
} IEEE_Cigre_DLLInterface_Instance;

#ifdef __cplusplus
extern "C" {
#endif

IEEE_CIGRE_EXPORT const IEEE_Cigre_DLLInterface_Model_Info *IEEE_CIGRE_CALL Model_GetInfo(void);
IEEE_CIGRE_EXPORT int32_T IEEE_CIGRE_CALL Model_FirstCall(IEEE_Cigre_DLLInterface_Instance *instance);
IEEE_CIGRE_EXPORT int32_T IEEE_CIGRE_CALL Model_CheckParameters(IEEE_Cigre_DLLInterface_Instance *instance);
IEEE_CIGRE_EXPORT int32_T IEEE_CIGRE_CALL Model_Initialize(IEEE_Cigre_DLLInterface_Instance *instance);
IEEE_CIGRE_EXPORT int32_T IEEE_CIGRE_CALL Model_Outputs(IEEE_Cigre_DLLInterface_Instance *instance);
IEEE_CIGRE_EXPORT int32_T IEEE_CIGRE_CALL Model_Iterate(IEEE_Cigre_DLLInterface_Instance *instance);
IEEE_CIGRE_EXPORT int32_T IEEE_CIGRE_CALL Model_Terminate(IEEE_Cigre_DLLInterface_Instance *instance);
IEEE_CIGRE_EXPORT int32_T IEEE_CIGRE_CALL Model_PrintInfo(void);

#ifdef __cplusplus
}
#endif

#endif /* IEEE_CIGRE_DLLINTERFACE_H */
