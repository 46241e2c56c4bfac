//! A library with the right ABI version but without the entry points, for the loader's tests.

/// The version the host speaks.
#[unsafe(no_mangle)]
pub extern "C" fn armcomp_abi_version() -> u32 {
    armcomp_sdk::abi::ABI_VERSION
}

/// No types.
#[unsafe(no_mangle)]
pub extern "C" fn armcomp_type_count() -> u32 {
    0
}
