//! A library that claims a plugin ABI version this host does not speak, for the loader's tests.

/// A version no armcomp speaks.
#[unsafe(no_mangle)]
pub extern "C" fn armcomp_abi_version() -> u32 {
    armcomp_sdk::abi::ABI_VERSION + 1000
}
