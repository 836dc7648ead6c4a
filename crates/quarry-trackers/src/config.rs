//! The one configuration convention of every tracker: [`TrackerConfig`] and [`PresetName`].

use serde::Serialize;
use serde::de::DeserializeOwned;

use crate::TrackerError;

/// A tracker's named presets: an enum with one variant per preset.
pub trait PresetName: Copy + Eq + std::fmt::Debug + Send + Sync + 'static {
    /// Every preset, the default (the paper's) first.
    const ALL: &'static [Self];
    /// The name a user types (`kf-gnn`, `paper`, ...): lower case, words joined by `-`.
    fn name(self) -> &'static str;
    /// One line saying what the preset is (shown by `--help`).
    fn about(self) -> &'static str;
    /// Which tracker the presets belong to (for error messages).
    const TRACKER: &'static str;

    /// The preset called `name` (`_` and `-` are interchangeable).
    fn parse(name: &str) -> Result<Self, TrackerError> {
        let norm = name.trim().replace('_', "-");
        Self::ALL
            .iter()
            .copied()
            .find(|p| p.name() == norm)
            .ok_or_else(|| TrackerError::UnknownPreset {
                tracker: Self::TRACKER,
                name: name.to_owned(),
                expected: Self::ALL
                    .iter()
                    .map(|p| p.name())
                    .collect::<Vec<_>>()
                    .join(", "),
            })
    }
}

/// The one configuration convention of every tracker.
///
/// Each tracker has a configuration type (`SlamotConfig`, `LidarPeopleConfig`, ...) and an enum
/// of named presets. The convention:
/// - `Default` is the paper's configuration, and is one of the presets;
/// - [`TrackerConfig::preset`] gives the configuration of a named preset;
/// - TOML is read *over a preset*: keys missing from the file keep that preset's values, unknown
///   keys are an error ([`TrackerConfig::from_toml`]); a top-level `preset = "name"` key in the
///   file chooses the base preset when the caller does not;
/// - [`TrackerConfig::validate`] checks every field and every rule between fields, and is the
///   only place those rules are written. It is called once, where a configuration is read (the
///   TOML functions here) or where a tracker is built from one.
///
/// Adding a preset is one variant (with its doc line) in the tracker's preset enum, its arm in
/// the tracker's `preset()` and its name in `Preset::ALL`: all in the tracker's `config.rs`.
///
/// ```
/// use quarry_trackers::lidar_people::{LidarPeopleConfig, Preset};
/// use quarry_trackers::{PresetName, TrackerConfig};
/// // TOML over the kf-gnn preset: one key changed, every other key from kf-gnn
/// let cfg = LidarPeopleConfig::from_toml("kf_sigma_r = 0.05", Some(Preset::KfGnn))?;
/// assert_eq!(cfg.preset, Preset::KfGnn);
/// assert_eq!(cfg.kf_sigma_r, 0.05);
/// // the file may name its preset itself
/// let cfg = LidarPeopleConfig::from_toml("preset = \"literal\"", None)?;
/// assert_eq!(cfg, LidarPeopleConfig::preset(Preset::Literal));
/// // unknown keys and bad values are errors that name them
/// assert!(LidarPeopleConfig::from_toml("kf_sigma_x = 1", None).is_err());
/// assert!(LidarPeopleConfig::from_toml("kf_sigma_r = -1", None).is_err());
/// assert_eq!(Preset::parse("kf-gnn")?, Preset::KfGnn);
/// # Ok::<(), quarry_trackers::TrackerError>(())
/// ```
pub trait TrackerConfig: Clone + Default + PartialEq + Serialize + DeserializeOwned {
    /// The tracker's preset enum.
    type Preset: PresetName;
    /// The tracker's name in messages (`slamot`, `lidar_people`, `rgbd_person`, ...).
    const NAME: &'static str;

    /// The configuration of a named preset (not validated: presets are valid by construction,
    /// and a test checks it).
    fn preset(p: Self::Preset) -> Self;

    /// Checks every field and every rule between fields.
    fn validate(&self) -> Result<(), TrackerError>;

    /// Parses TOML laid over a preset and validates the result.
    ///
    /// The base is `preset` when given, else the file's top-level `preset = "name"` key, else
    /// `Default`. Keys missing from the file keep the base's values (tables merge key by key);
    /// an unknown key, a value of the wrong type or a value that fails [`validate`](Self::validate)
    /// is an error. When both `preset` and the file's `preset` key are given and differ, that is
    /// an error too (say one or the other).
    fn from_toml(text: &str, preset: Option<Self::Preset>) -> Result<Self, TrackerError> {
        let mut user: toml::Table =
            toml::from_str(text).map_err(|e| toml_error(Self::NAME, text, e))?;
        let named = match user.remove("preset") {
            None => None,
            Some(toml::Value::String(s)) => Some(Self::Preset::parse(&s)?),
            Some(other) => {
                return Err(TrackerError::config(
                    Self::NAME,
                    format!("`preset` must be a string naming a preset, got {other}"),
                ));
            }
        };
        let base = match (preset, named) {
            (Some(a), Some(b)) if a != b => {
                return Err(TrackerError::config(
                    Self::NAME,
                    format!(
                        "the file says preset = {:?} but {:?} was asked for",
                        b.name(),
                        a.name()
                    ),
                ));
            }
            (Some(p), _) | (None, Some(p)) => Self::preset(p),
            (None, None) => Self::default(),
        };
        let cfg = overlay(&base, user, Self::NAME).map_err(|e| match e {
            OverlayError::Tracker(e) => e,
            OverlayError::Toml(e) => toml_error(Self::NAME, text, e),
        })?;
        cfg.validate()?;
        Ok(cfg)
    }

    /// Reads a TOML file over a preset ([`from_toml`](Self::from_toml)); the error names the
    /// file. Files over 1 MiB are refused (a configuration is a few kilobytes).
    fn from_toml_file(
        path: &std::path::Path,
        preset: Option<Self::Preset>,
    ) -> Result<Self, TrackerError> {
        const MAX: u64 = 1 << 20;
        let meta = std::fs::metadata(path)
            .map_err(|e| TrackerError::config(Self::NAME, format!("{}: {e}", path.display())))?;
        if meta.len() > MAX {
            return Err(TrackerError::config(
                Self::NAME,
                format!(
                    "{}: {} bytes is too large for a configuration (at most {MAX})",
                    path.display(),
                    meta.len()
                ),
            ));
        }
        let text = std::fs::read_to_string(path)
            .map_err(|e| TrackerError::config(Self::NAME, format!("{}: {e}", path.display())))?;
        Self::from_toml(&text, preset).map_err(|e| match e {
            TrackerError::Config { tracker, reason } => TrackerError::Config {
                tracker,
                reason: format!("{}: {reason}", path.display()),
            },
            TrackerError::Toml {
                tracker,
                line,
                key,
                error,
                ..
            } => TrackerError::Toml {
                tracker,
                file: Some(path.display().to_string()),
                line,
                key,
                error,
            },
            other => other,
        })
    }

    /// The configuration as TOML text (every key; reads back to the same value).
    fn to_toml(&self) -> Result<String, TrackerError> {
        toml::to_string(self).map_err(|e| TrackerError::config(Self::NAME, e.to_string()))
    }
}

/// Why [`overlay`] failed: the preset itself (a bug), or the user's values.
enum OverlayError {
    Tracker(TrackerError),
    Toml(toml::de::Error),
}

/// `user` laid over `base`: tables merge key by key (recursively), any other value replaces.
fn overlay<C: TrackerConfig>(
    base: &C,
    user: toml::Table,
    tracker: &'static str,
) -> Result<C, OverlayError> {
    let toml::Value::Table(mut merged) = toml::Value::try_from(base).map_err(|e| {
        OverlayError::Tracker(TrackerError::config(
            tracker,
            format!("preset to TOML: {e}"),
        ))
    })?
    else {
        return Err(OverlayError::Tracker(TrackerError::config(
            tracker,
            "a configuration must serialise to a TOML table",
        )));
    };
    merge(&mut merged, user);
    toml::Value::Table(merged)
        .try_into()
        .map_err(OverlayError::Toml)
}

/// A TOML error located in the user's `text`: a syntax error has its own span; an error of
/// the merged document (wrong type, unknown key) names a key path, which is looked up in the
/// user's document for its line, since the merged document is no text the user ever saw.
fn toml_error(tracker: &'static str, text: &str, e: toml::de::Error) -> TrackerError {
    let line_of = |at: usize| text[..at.min(text.len())].matches('\n').count() + 1;
    let (line, key) = if let Some(span) = e.span() {
        (Some(line_of(span.start)), None)
    } else {
        let path = error_key_path(&e);
        let line = key_offset(text, &path).map(line_of);
        let key = (!path.is_empty()).then(|| path.join("."));
        (line, key)
    };
    TrackerError::Toml {
        tracker,
        file: None,
        line,
        key,
        error: Box::new(e),
    }
}

/// The key path a deserialisation error is about: the table path it names (`in `model``)
/// plus, for an unknown field, the field itself.
fn error_key_path(e: &toml::de::Error) -> Vec<String> {
    let full = e.to_string();
    let mut path: Vec<String> = full
        .lines()
        .rev()
        .find_map(|l| l.strip_prefix("in `").and_then(|r| r.strip_suffix('`')))
        .map(|p| p.split('.').map(str::to_owned).collect())
        .unwrap_or_default();
    if let Some(rest) = e.message().strip_prefix("unknown field `")
        && let Some(field) = rest.split('`').next()
    {
        path.push(field.to_owned());
    }
    path
}

/// Byte offset of the key at `path` in the TOML `text` (its last segment), if present.
fn key_offset(text: &str, path: &[String]) -> Option<usize> {
    let doc = toml::de::DeTable::parse(text).ok()?;
    let mut table = doc.get_ref();
    let (last, parents) = path.split_last()?;
    for p in parents {
        let (_, v) = table
            .iter()
            .find(|(k, _)| k.get_ref().as_ref() == p.as_str())?;
        match v.get_ref() {
            toml::de::DeValue::Table(t) => table = t,
            _ => return None,
        }
    }
    table
        .iter()
        .find(|(k, _)| k.get_ref().as_ref() == last.as_str())
        .map(|(k, _)| k.span().start)
}

fn merge(base: &mut toml::Table, user: toml::Table) {
    for (k, v) in user {
        match (base.get_mut(&k), v) {
            (Some(toml::Value::Table(b)), toml::Value::Table(u)) => merge(b, u),
            (_, v) => {
                base.insert(k, v);
            }
        }
    }
}

/// What every configuration of the crate must satisfy (a test helper, used for each tracker by
/// the test below): the default is the first preset; every preset validates, has a description,
/// parses back from its name (with `_` for `-` too) and reads back from its own TOML over
/// itself, over the default and named in the file; an empty file is the preset; an unknown key
/// is an error.
#[cfg(test)]
pub(crate) fn check_convention<C: TrackerConfig + std::fmt::Debug>() {
    let presets = <C::Preset as PresetName>::ALL;
    assert!(!presets.is_empty(), "{}: no preset", C::NAME);
    assert_eq!(C::preset(presets[0]), C::default(), "{}", C::NAME);
    for &p in presets {
        let c = C::preset(p);
        c.validate()
            .unwrap_or_else(|e| panic!("{} preset {}: {e}", C::NAME, p.name()));
        assert!(!p.about().is_empty(), "{} preset {}", C::NAME, p.name());
        assert_eq!(C::Preset::parse(p.name()).unwrap(), p);
        assert_eq!(C::Preset::parse(&p.name().replace('-', "_")).unwrap(), p);
        let text = c.to_toml().unwrap();
        assert_eq!(C::from_toml(&text, Some(p)).unwrap(), c, "{text}");
        assert_eq!(C::from_toml(&text, None).unwrap(), c, "{text}");
        // the file naming its preset (configurations with a `preset` field write it themselves)
        let table: toml::Table = toml::from_str(&text).unwrap();
        let named = if table.contains_key("preset") {
            text.clone()
        } else {
            format!("preset = {:?}\n{text}", p.name())
        };
        assert_eq!(C::from_toml(&named, None).unwrap(), c, "{named}");
        assert_eq!(C::from_toml("", Some(p)).unwrap(), c);
    }
    let e = C::from_toml("\n\nno_such_key_in_any_config = 1", None).unwrap_err();
    assert!(matches!(e, TrackerError::Toml { .. }), "{}: {e:?}", C::NAME);
    // the user's line and key, not the merged document's
    let text = e.to_string();
    assert!(
        text.contains("line 3, key `no_such_key_in_any_config`"),
        "{}: {text}",
        C::NAME
    );
    assert!(C::Preset::parse("no-such-preset").is_err());
}

#[cfg(test)]
mod tests {
    use super::check_convention;
    use crate::TrackerConfig as _;

    #[test]
    fn errors_name_the_users_line_and_key() {
        use crate::rgbd_person::RgbdPersonConfig;
        let e = RgbdPersonConfig::from_toml("c_base = 0.8\n[model]\n\nn = \"three\"\n", None)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("line 4, key `model.n`") && e.contains("invalid type"),
            "{e}"
        );
        assert!(!e.contains('\n'), "{e}");
        let e = RgbdPersonConfig::from_toml("[model]\nnn = 3\n", None)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("line 2, key `model.nn`") && e.contains("unknown field"),
            "{e}"
        );
        // a syntax error keeps toml's own location
        let e = RgbdPersonConfig::from_toml("c_base = \n", None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("line 1"), "{e}");
    }

    #[test]
    fn every_tracker_configuration_follows_the_convention() {
        check_convention::<crate::slamot::SlamotConfig>();
        check_convention::<crate::lidar_people::LidarPeopleConfig>();
        check_convention::<crate::rgbd_person::RgbdPersonConfig>();
        check_convention::<crate::cv_jpda::JpdaTrackerConfig>();
    }
}
