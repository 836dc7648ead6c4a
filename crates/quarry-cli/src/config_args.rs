//! `--preset NAME` and `--config FILE.toml`: the one pair of configuration flags every tracker
//! command shares (`#[command(flatten)] cfg: ConfigArgs<Preset>`), over the library's
//! [`TrackerConfig`] convention (TOML laid over the preset; missing keys from the preset).

use std::ffi::OsStr;
use std::marker::PhantomData;
use std::path::PathBuf;

use clap::builder::{PossibleValue, TypedValueParser};
use clap::error::{ContextKind, ContextValue, ErrorKind};
use quarry_trackers::{PresetName, TrackerConfig, TrackerError};

/// A clap value parser for a tracker's preset enum: the preset names are the possible values
/// (listed with their one-line descriptions in `--help`), and `_` may stand for `-`.
#[derive(Debug, Clone)]
pub struct PresetParser<P>(PhantomData<P>);

impl<P> PresetParser<P> {
    /// The parser.
    pub fn new() -> Self {
        Self(PhantomData)
    }
}

impl<P: PresetName> TypedValueParser for PresetParser<P> {
    type Value = P;

    fn parse_ref(
        &self,
        cmd: &clap::Command,
        arg: Option<&clap::Arg>,
        value: &OsStr,
    ) -> Result<P, clap::Error> {
        let s = value.to_string_lossy();
        P::parse(&s).map_err(|_| {
            let mut e = clap::Error::new(ErrorKind::InvalidValue).with_cmd(cmd);
            e.insert(
                ContextKind::InvalidArg,
                ContextValue::String(arg.map_or_else(|| "--preset".into(), ToString::to_string)),
            );
            e.insert(
                ContextKind::InvalidValue,
                ContextValue::String(s.into_owned()),
            );
            e.insert(
                ContextKind::ValidValue,
                ContextValue::Strings(P::ALL.iter().map(|p| p.name().to_owned()).collect()),
            );
            e
        })
    }

    fn possible_values(&self) -> Option<Box<dyn Iterator<Item = PossibleValue> + '_>> {
        Some(Box::new(
            P::ALL
                .iter()
                .map(|p| PossibleValue::new(p.name()).help(p.about())),
        ))
    }
}

/// The shared configuration flags of a tracker command.
#[derive(Debug, Clone, clap::Args)]
pub struct ConfigArgs<P: PresetName> {
    /// Named preset of the tracker's configuration (default: the paper's; or the `preset` key
    /// of the --config file).
    #[arg(long, value_name = "NAME", value_parser = PresetParser::<P>::new())]
    pub preset: Option<P>,
    /// TOML configuration laid over the preset: keys missing from the file keep the preset's
    /// values; unknown keys and bad values are errors naming them.
    #[arg(long, value_name = "FILE.toml")]
    pub config: Option<PathBuf>,
}

impl<P: PresetName> ConfigArgs<P> {
    /// The configuration these flags ask for, validated (once, here).
    pub fn load<C: TrackerConfig<Preset = P>>(&self) -> Result<C, TrackerError> {
        if let Some(path) = &self.config {
            C::from_toml_file(path, self.preset)
        } else {
            let c = self.preset.map_or_else(C::default, C::preset);
            c.validate()?;
            Ok(c)
        }
    }
}

impl<P: PresetName> Default for ConfigArgs<P> {
    fn default() -> Self {
        Self {
            preset: None,
            config: None,
        }
    }
}
