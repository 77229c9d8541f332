//! Service names. Every daemon instance owns the names under `ember/<instance>/`, so two daemons
//! run side by side under different instance names.

/// Default instance name.
pub const DEFAULT_INSTANCE: &str = "default";

/// Name of service `kind` (`cloud`, `objects`, `joints`, `plan`, `status`) of `instance`.
pub fn service(instance: &str, kind: &str) -> String {
    format!("ember/{instance}/{kind}")
}

/// True when `instance` is usable in a service name (letters, digits, `-`, `_`, 1–64 chars).
pub fn valid_instance(instance: &str) -> bool {
    (1..=64).contains(&instance.len())
        && instance
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
}
