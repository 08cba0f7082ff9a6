//! Limits on the work one script may ask for.
//!
//! A script is a program: a count, a nested group or a chain of includes can ask for more
//! instances, placement tries or file reads than any machine can give. [`Limits`] bounds
//! each of them; every limit is checked *before* the work (or the allocation) it bounds, and
//! breaking one is a [`LayoutError::Limit`] naming the script's place, the limit and the
//! environment variable that raises it.
//!
//! [`crate::load`] and [`crate::load_str`] read the limits from the environment
//! ([`Limits::from_env`]); [`crate::load_with`] and [`crate::load_str_with`] take them from
//! the caller. The limits travel with the loaded script ([`crate::LoadedScript::limits`]), so
//! [`crate::resolve()`] and [`crate::append_edits`] apply the same ones.

use crate::error::{LayoutError, Location};
use std::fmt;

/// Limits set for the whole process (by [`Limits::set_for_process`]), in [`Limit::ALL`]'s order.
static PROCESS_LIMITS: std::sync::Mutex<[Option<u64>; 6]> = std::sync::Mutex::new([None; 6]);

/// One of the limits of [`Limits`] (for error messages and environment variables).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Limit {
    /// [`Limits::max_instances`].
    Instances,
    /// [`Limits::max_scatter_tries`].
    ScatterTries,
    /// [`Limits::max_region_points`].
    RegionPoints,
    /// [`Limits::max_include_depth`].
    IncludeDepth,
    /// [`Limits::max_file_loads`].
    FileLoads,
    /// [`Limits::max_file_bytes`].
    FileBytes,
}

impl Limit {
    /// Every limit, in the order of [`Limits`]' fields.
    pub const ALL: [Limit; 6] = [
        Limit::Instances,
        Limit::ScatterTries,
        Limit::RegionPoints,
        Limit::IncludeDepth,
        Limit::FileLoads,
        Limit::FileBytes,
    ];

    /// The environment variable that sets this limit (read by [`Limits::from_env`]).
    pub fn env_var(self) -> &'static str {
        match self {
            Limit::Instances => "ASSETFIELD_MAX_INSTANCES",
            Limit::ScatterTries => "ASSETFIELD_MAX_SCATTER_TRIES",
            Limit::RegionPoints => "ASSETFIELD_MAX_REGION_POINTS",
            Limit::IncludeDepth => "ASSETFIELD_MAX_INCLUDE_DEPTH",
            Limit::FileLoads => "ASSETFIELD_MAX_FILE_LOADS",
            Limit::FileBytes => "ASSETFIELD_MAX_SCRIPT_BYTES",
        }
    }

    /// The name `--limit NAME=N` gives it on the command line.
    pub fn flag_name(self) -> &'static str {
        match self {
            Limit::Instances => "instances",
            Limit::ScatterTries => "scatter-tries",
            Limit::RegionPoints => "region-points",
            Limit::IncludeDepth => "include-depth",
            Limit::FileLoads => "file-loads",
            Limit::FileBytes => "script-bytes",
        }
    }

    /// The limit that `--limit NAME=N` names.
    pub fn from_flag_name(name: &str) -> Option<Limit> {
        Limit::ALL.into_iter().find(|l| l.flag_name() == name)
    }

    /// What the limit counts, in words ("instances per script").
    pub fn unit(self) -> &'static str {
        match self {
            Limit::Instances => "instances per script",
            Limit::ScatterTries => "scatter placement tries per script",
            Limit::RegionPoints => "points per scatter region",
            Limit::IncludeDepth => "nested `base`/`include` levels",
            Limit::FileLoads => {
                "file loads per script (every `base` and `include`, repeats counted)"
            }
            Limit::FileBytes => "bytes per script file",
        }
    }
}

impl fmt::Display for Limit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.unit())
    }
}

/// Bounds on what one script (its main file with everything it refers to) may ask for.
///
/// The defaults leave real scenes far below every bound (the largest scene of `scenes/` has
/// a few hundred instances in under ten files) and keep the worst script within about a
/// second of work and a few hundred megabytes of memory. Raise a limit with its environment
/// variable ([`Limit::env_var`]) or by setting the field.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limits {
    /// Instances one script may place, counted over every item and every `Duplicate` edit
    /// (removed instances included: they were made). Default 1,000,000: while resolving, an
    /// instance takes about 700 bytes with its key, source location and indexes, so this caps
    /// resolution at well under 1 GB; a dense street or hall has a few thousand instances.
    /// At most `u32::MAX` (ids are 32-bit). `ASSETFIELD_MAX_INSTANCES`.
    pub max_instances: usize,
    /// Random placement tries of all `Scatter` items of a script together (each scatter also
    /// gives up after 500 tries per instance it asks for). Default 10,000,000: about a second
    /// of work; a scatter that finds room takes a few tries per instance.
    /// `ASSETFIELD_MAX_SCATTER_TRIES`.
    pub max_scatter_tries: u64,
    /// Points of one `Polygon` scatter region (every try tests the point against every
    /// edge). Default 1,000: a hand-written or traced outline has tens.
    /// `ASSETFIELD_MAX_REGION_POINTS`.
    pub max_region_points: usize,
    /// Nesting of `base` and `include` references (the main file is level 1). Default 32: an
    /// edit of an edit of a scene with its asset files is 4 or 5 levels deep.
    /// `ASSETFIELD_MAX_INCLUDE_DEPTH`.
    pub max_include_depth: usize,
    /// File loads of one script, the main file included, counting a file once per `base` or
    /// `include` that names it (an asset file included by two files counts twice; it is read
    /// and parsed once). Default 1,024: a scene with a library of asset files needs tens; a
    /// chain of files each including the next twice would need 2^depth.
    /// `ASSETFIELD_MAX_FILE_LOADS`.
    pub max_file_loads: usize,
    /// Size of one script file in bytes. Default 16 MiB: about 300,000 instance lines, far
    /// more than anyone writes by hand; a generated layout (`assetfield mine`) of a large
    /// scene is a few hundred kilobytes. `ASSETFIELD_MAX_SCRIPT_BYTES`.
    pub max_file_bytes: u64,
}

impl Limits {
    /// The default limits (see the fields).
    pub const DEFAULT: Limits = Limits {
        max_instances: 1_000_000,
        max_scatter_tries: 10_000_000,
        max_region_points: 1_000,
        max_include_depth: 32,
        max_file_loads: 1_024,
        max_file_bytes: 16 * 1024 * 1024,
    };

    /// No limit at all (for tests and trusted generated scripts; still at most `u32::MAX`
    /// instances).
    pub const UNLIMITED: Limits = Limits {
        max_instances: u32::MAX as usize,
        max_scatter_tries: u64::MAX,
        max_region_points: usize::MAX,
        max_include_depth: usize::MAX,
        max_file_loads: usize::MAX,
        max_file_bytes: u64::MAX,
    };

    /// The defaults, each replaced by its environment variable when set
    /// (`ASSETFIELD_MAX_INSTANCES=2000000`). A variable that is not a non-negative integer
    /// is an error naming it.
    ///
    /// Values set for the whole process ([`Limits::set_for_process`], the CLI's `--limit`)
    /// come last and win over the variables.
    pub fn from_env() -> Result<Limits, LayoutError> {
        let mut limits = Limits::from_lookup(|name| std::env::var(name).ok())?;
        let set = PROCESS_LIMITS.lock().unwrap_or_else(|p| p.into_inner());
        for (limit, value) in Limit::ALL.into_iter().zip(set.iter()) {
            if let Some(v) = value {
                limits.set(limit, *v);
            }
        }
        Ok(limits)
    }

    /// Whether `limit` was set for this process (its environment variable or
    /// [`Limits::set_for_process`]) rather than left at its default: a tool with a tighter
    /// default of its own (the editor) keeps what a person asked for.
    pub fn explicitly_set(limit: Limit) -> bool {
        let k = Limit::ALL.iter().position(|l| *l == limit).unwrap_or(0);
        std::env::var_os(limit.env_var()).is_some()
            || PROCESS_LIMITS.lock().unwrap_or_else(|p| p.into_inner())[k].is_some()
    }

    /// Set one limit for every script this process loads from now on (what the CLI's
    /// `--limit NAME=N` does); it wins over the environment variable.
    pub fn set_for_process(limit: Limit, value: u64) {
        let k = Limit::ALL.iter().position(|l| *l == limit).unwrap_or(0);
        PROCESS_LIMITS.lock().unwrap_or_else(|p| p.into_inner())[k] = Some(value);
    }

    /// [`Limits::from_env`] with the variables looked up by `var` (testable without touching
    /// the process environment).
    pub fn from_lookup(var: impl Fn(&str) -> Option<String>) -> Result<Limits, LayoutError> {
        let mut limits = Limits::DEFAULT;
        for limit in Limit::ALL {
            let Some(text) = var(limit.env_var()) else { continue };
            let value: u64 = text.trim().parse().map_err(|_| LayoutError::LimitSetting {
                variable: limit.env_var(),
                value: text.clone(),
            })?;
            limits.set(limit, value);
        }
        Ok(limits)
    }

    /// The value of one limit.
    pub fn get(&self, limit: Limit) -> u64 {
        let wide = |v: usize| u64::try_from(v).unwrap_or(u64::MAX);
        match limit {
            Limit::Instances => wide(self.max_instances.min(u32::MAX as usize)),
            Limit::ScatterTries => self.max_scatter_tries,
            Limit::RegionPoints => wide(self.max_region_points),
            Limit::IncludeDepth => wide(self.max_include_depth),
            Limit::FileLoads => wide(self.max_file_loads),
            Limit::FileBytes => self.max_file_bytes,
        }
    }

    /// Set one limit (values beyond what the platform counts are clamped).
    pub fn set(&mut self, limit: Limit, value: u64) {
        let narrow = |v: u64| usize::try_from(v).unwrap_or(usize::MAX);
        match limit {
            Limit::Instances => self.max_instances = narrow(value.min(u64::from(u32::MAX))),
            Limit::ScatterTries => self.max_scatter_tries = value,
            Limit::RegionPoints => self.max_region_points = narrow(value),
            Limit::IncludeDepth => self.max_include_depth = narrow(value),
            Limit::FileLoads => self.max_file_loads = narrow(value),
            Limit::FileBytes => self.max_file_bytes = value,
        }
    }

    /// The error for asking more than `limit` allows at `location`; `what` says what was
    /// asked ("Row(count: 4294967295) would place 4294967295 instances").
    pub fn exceeded(&self, limit: Limit, location: &Location, what: String) -> LayoutError {
        LayoutError::Limit { location: location.clone(), limit, value: self.get(limit), what }
    }
}

impl Default for Limits {
    fn default() -> Self {
        Limits::DEFAULT
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn environment_variables_raise_limits_and_bad_values_are_named() {
        let l = Limits::from_lookup(|v| (v == "ASSETFIELD_MAX_INSTANCES").then(|| "25".into()));
        assert_eq!(l.unwrap().max_instances, 25);
        assert_eq!(Limits::from_lookup(|_| None).unwrap(), Limits::default());
        let e = Limits::from_lookup(|v| (v == "ASSETFIELD_MAX_FILE_LOADS").then(|| "many".into()))
            .unwrap_err()
            .to_string();
        assert!(e.contains("ASSETFIELD_MAX_FILE_LOADS") && e.contains("many"), "{e}");
        let mut l = Limits::default();
        l.set(Limit::Instances, u64::MAX);
        assert_eq!(l.get(Limit::Instances), u64::from(u32::MAX));
    }
}
