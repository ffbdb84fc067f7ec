//! The few structs of XLA's FFI C API (`xla/ffi/api/c_api.h`, API version 0.x) that the
//! handlers read: the call frame, its buffers, the metadata query, and error creation. The
//! C API is versioned and every struct carries its size; only fields present since its
//! first version are read here.

use std::ffi::{CString, c_char, c_int, c_void};

/// `XLA_FFI_Extension_Base`.
#[repr(C)]
pub struct ExtensionBase {
    pub struct_size: usize,
    pub kind: c_int,
    pub next: *mut ExtensionBase,
}

/// `XLA_FFI_Extension_Metadata`: the registration's query of a handler's version and traits.
pub const EXTENSION_METADATA: c_int = 1;

/// `XLA_FFI_Api_Version`.
#[repr(C)]
pub struct ApiVersion {
    pub struct_size: usize,
    pub extension_start: *mut ExtensionBase,
    pub major: c_int,
    pub minor: c_int,
}

/// `XLA_FFI_Metadata` (its first fields; newer versions append more).
#[repr(C)]
pub struct Metadata {
    pub struct_size: usize,
    pub api_version: ApiVersion,
    pub traits: u32,
}

/// `XLA_FFI_Metadata_Extension`.
#[repr(C)]
pub struct MetadataExtension {
    pub base: ExtensionBase,
    pub metadata: *mut Metadata,
}

/// `XLA_FFI_Error_Create_Args`.
#[repr(C)]
struct ErrorCreateArgs {
    struct_size: usize,
    extension_start: *mut ExtensionBase,
    message: *const c_char,
    errc: c_int,
}

type ErrorCreate = unsafe extern "C" fn(*mut ErrorCreateArgs) -> *mut c_void;

/// `XLA_FFI_Api` (its first fields: the version, and error creation).
#[repr(C)]
pub struct Api {
    pub struct_size: usize,
    pub extension_start: *mut ExtensionBase,
    pub api_version: ApiVersion,
    pub internal_api: *const c_void,
    error_create: Option<ErrorCreate>,
}

/// `XLA_FFI_Buffer`.
#[repr(C)]
pub struct Buffer {
    pub struct_size: usize,
    pub extension_start: *mut ExtensionBase,
    pub dtype: c_int,
    pub data: *mut c_void,
    pub rank: i64,
    pub dims: *const i64,
}

/// `XLA_FFI_Args` and `XLA_FFI_Rets` (the same layout).
#[repr(C)]
pub struct Values {
    pub struct_size: usize,
    pub extension_start: *mut ExtensionBase,
    pub size: i64,
    pub types: *const c_int,
    pub values: *const *mut c_void,
}

/// `XLA_FFI_Attrs`.
#[repr(C)]
pub struct Attrs {
    pub struct_size: usize,
    pub extension_start: *mut ExtensionBase,
    pub size: i64,
    pub types: *const c_int,
    pub names: *const *const c_void,
    pub attrs: *const *mut c_void,
}

/// `XLA_FFI_CallFrame`.
#[repr(C)]
pub struct CallFrame {
    pub struct_size: usize,
    pub extension_start: *mut ExtensionBase,
    pub api: *const Api,
    pub ctx: *mut c_void,
    pub stage: c_int,
    pub args: Values,
    pub rets: Values,
    pub attrs: Attrs,
}

/// `XLA_FFI_ExecutionStage_EXECUTE`.
pub const STAGE_EXECUTE: c_int = 3;
/// `XLA_FFI_ArgType_BUFFER` / `XLA_FFI_RetType_BUFFER`.
pub const TYPE_BUFFER: c_int = 1;

/// `XLA_FFI_Error_Code_INVALID_ARGUMENT`.
pub const INVALID_ARGUMENT: c_int = 3;
/// `XLA_FFI_Error_Code_FAILED_PRECONDITION`.
pub const FAILED_PRECONDITION: c_int = 9;
/// `XLA_FFI_Error_Code_INTERNAL`.
pub const INTERNAL: c_int = 13;

/// `XLA_FFI_DataType`: the element types the handlers read and write.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DataType {
    Pred,
    S8,
    S16,
    S32,
    S64,
    U8,
    U16,
    U32,
    U64,
    F32,
    F64,
}

impl DataType {
    /// The type of an `XLA_FFI_DataType` code (`None`: one the handlers do not take).
    pub fn from_code(code: c_int) -> Option<Self> {
        Some(match code {
            1 => DataType::Pred,
            2 => DataType::S8,
            3 => DataType::S16,
            4 => DataType::S32,
            5 => DataType::S64,
            6 => DataType::U8,
            7 => DataType::U16,
            8 => DataType::U32,
            9 => DataType::U64,
            11 => DataType::F32,
            12 => DataType::F64,
            _ => return None,
        })
    }

    /// Bytes per element.
    pub fn size(self) -> usize {
        match self {
            DataType::Pred | DataType::S8 | DataType::U8 => 1,
            DataType::S16 | DataType::U16 | DataType::S32 | DataType::U32 | DataType::F32 => 4,
            DataType::S64 | DataType::U64 | DataType::F64 => 8,
        }
    }
}

/// A new `XLA_FFI_Error` with `message` (XLA takes ownership, and raises it in Python as an
/// `XlaRuntimeError`), or null where the API has no error creation (never in practice).
///
/// # Safety
/// `api` must be the call frame's API pointer.
pub unsafe fn error(api: *const Api, errc: c_int, message: &str) -> *mut c_void {
    let text = CString::new(message.replace('\0', " ")).unwrap_or_default();
    // SAFETY: the caller passes the call frame's API, valid for the call.
    let Some(create) = (unsafe { api.as_ref() }).and_then(|a| a.error_create) else {
        return std::ptr::null_mut();
    };
    let mut args = ErrorCreateArgs {
        struct_size: std::mem::size_of::<ErrorCreateArgs>(),
        extension_start: std::ptr::null_mut(),
        message: text.as_ptr(),
        errc,
    };
    // SAFETY: a valid args struct; XLA copies the message before returning.
    unsafe { create(&mut args) }
}
