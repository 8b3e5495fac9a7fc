//! Stage kinds declared as data, like a GStreamer element's properties:
//! each kind lists its parameters ([`ParamSpec`]: name, type, default,
//! range or allowed values, unit, one line of doc) and its named, typed
//! ports ([`InPort`], [`OutPort`]). [`Params::resolve`] validates a stage's
//! parameters against that list (unknown keys, types, ranges, choices,
//! required fields), fills in the defaults and deserializes the kind's
//! typed parameters; [`KindSpec::describe`] prints the same list for
//! `vibroscope kinds KIND`. Checks that involve several fields (a hop no
//! longer than the window, `min_hz < max_hz`) stay in the kind's `plan`.
//!
//! ```
//! use vibroscope_core::spec::{Def, ParamSpec, ParamType::*};
//! const PARAMS: &[ParamSpec] = &[
//!     ParamSpec::new("fps", Float, Def::Float(2200.0))
//!         .above(0.0)
//!         .unit("Hz")
//!         .doc("frame rate"),
//!     ParamSpec::new("path", Path, Def::Required).doc("output file"),
//! ];
//! # let _ = PARAMS;
//! ```

use crate::config::{
    err, set_param, ConfigError, InputDecl, Origin, Param, Params, PipelineDecl, StageDecl,
};
use crate::item::PortType;
use crate::stage::{Node, StageError};
use serde::de::DeserializeOwned;
use serde::Serialize;
use std::fmt::{self, Write as _};
use toml::Value;

/// The TOML type of a parameter.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ParamType {
    Bool,
    Int,
    /// A number (integers are accepted).
    Float,
    Str,
    /// A file or directory path (a string).
    Path,
    /// One of a fixed set of strings.
    Choice(&'static [&'static str]),
    /// A number (in `range`) or one of these words (`gain = "auto"`).
    NumOr(&'static [&'static str]),
    /// An array of integers (each in `range`).
    Ints,
    /// An array of numbers (each in `range`).
    Floats,
    /// An inline table (its keys are checked by the kind's own types).
    Table,
    /// An array of inline tables.
    Tables,
}

impl fmt::Display for ParamType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            ParamType::Bool => "bool",
            ParamType::Int => "int",
            ParamType::Float => "float",
            ParamType::Str => "string",
            ParamType::Path => "path",
            ParamType::Choice(_) => "choice",
            ParamType::NumOr(_) => "float|word",
            ParamType::Ints => "[int]",
            ParamType::Floats => "[float]",
            ParamType::Table => "table",
            ParamType::Tables => "[table]",
        })
    }
}

impl ParamType {
    fn expected(&self) -> &'static str {
        match self {
            ParamType::Bool => "a boolean",
            ParamType::Int => "an integer",
            ParamType::Float => "a number",
            ParamType::Str | ParamType::Path | ParamType::Choice(_) => "a string",
            ParamType::NumOr(_) => "a number or a word",
            ParamType::Ints => "an array of integers",
            ParamType::Floats => "an array of numbers",
            ParamType::Table => "a table",
            ParamType::Tables => "an array of tables",
        }
    }
}

/// A parameter's default.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Def {
    /// The stage cannot be built without it.
    Required,
    /// Absent means "automatic" (the doc says what that is).
    Optional,
    Bool(bool),
    Int(i64),
    Float(f64),
    Str(&'static str),
    /// Any other value, as TOML text (`"[1, 2]"`, `"{ type = \"tone\" }"`).
    Toml(&'static str),
}

impl Def {
    /// The default as a TOML value (`None` for required and optional).
    pub fn value(&self) -> Option<Value> {
        Some(match *self {
            Def::Required | Def::Optional => return None,
            Def::Bool(b) => Value::Boolean(b),
            Def::Int(i) => Value::Integer(i),
            Def::Float(x) => Value::Float(x),
            Def::Str(s) => Value::String(s.to_string()),
            Def::Toml(t) => crate::config::parse_value(t),
        })
    }
}

impl fmt::Display for Def {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Def::Required => f.write_str("required"),
            Def::Optional => f.write_str("auto"),
            Def::Bool(b) => write!(f, "{b}"),
            Def::Int(i) => write!(f, "{i}"),
            Def::Float(x) => write!(f, "{x}"),
            Def::Str(s) => write!(f, "{s}"),
            Def::Toml(t) => f.write_str(t),
        }
    }
}

/// The valid values of a number (each element's, for arrays).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Range {
    /// Any value (floats must still be finite).
    Any,
    /// `lo..=hi`.
    Int(i64, i64),
    /// Between `lo` and `hi`, each bound inclusive or not; finite.
    Float {
        lo: f64,
        lo_open: bool,
        hi: f64,
        hi_open: bool,
    },
}

impl Range {
    fn contains_f(&self, x: f64) -> bool {
        match *self {
            Range::Any => x.is_finite(),
            Range::Int(lo, hi) => x >= lo as f64 && x <= hi as f64,
            Range::Float {
                lo,
                lo_open,
                hi,
                hi_open,
            } => {
                x.is_finite()
                    && if lo_open { x > lo } else { x >= lo }
                    && if hi_open { x < hi } else { x <= hi }
            }
        }
    }
}

impl fmt::Display for Range {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Range::Any => Ok(()),
            Range::Int(lo, i64::MAX) => write!(f, ">= {lo}"),
            Range::Int(lo, hi) => write!(f, "{lo}..={hi}"),
            Range::Float {
                lo,
                lo_open,
                hi,
                hi_open,
            } => {
                let l = if lo_open { ">" } else { ">=" };
                let h = if hi_open { "<" } else { "<=" };
                match (lo.is_finite(), hi.is_finite()) {
                    (true, true) => write!(f, "{l} {lo} and {h} {hi}"),
                    (true, false) => write!(f, "{l} {lo}"),
                    (false, true) => write!(f, "{h} {hi}"),
                    (false, false) => f.write_str("finite"),
                }
            }
        }
    }
}

/// One parameter of a stage kind.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParamSpec {
    pub name: &'static str,
    pub ty: ParamType,
    pub default: Def,
    pub range: Range,
    /// Unit of the value (`"Hz"`, `"px"`, `"samples"`); empty when none.
    pub unit: &'static str,
    /// One line.
    pub doc: &'static str,
}

impl ParamSpec {
    /// A parameter without its name yet: [`params!`](crate::params) names
    /// it after its field.
    pub const fn of(ty: ParamType, default: Def) -> Self {
        Self::new("", ty, default)
    }
    /// The same parameter named `name` (a shared declaration, such as the
    /// region's, under a field's name).
    pub const fn named(self, name: &'static str) -> Self {
        Self { name, ..self }
    }
    pub const fn new(name: &'static str, ty: ParamType, default: Def) -> Self {
        Self {
            name,
            ty,
            default,
            range: Range::Any,
            unit: "",
            doc: "",
        }
    }
    pub const fn unit(self, unit: &'static str) -> Self {
        Self { unit, ..self }
    }
    pub const fn doc(self, doc: &'static str) -> Self {
        Self { doc, ..self }
    }
    /// Integers in `lo..=hi`.
    pub const fn ints(self, lo: i64, hi: i64) -> Self {
        Self {
            range: Range::Int(lo, hi),
            ..self
        }
    }
    /// Numbers in `lo..=hi`.
    pub const fn floats(self, lo: f64, hi: f64) -> Self {
        Self {
            range: Range::Float {
                lo,
                lo_open: false,
                hi,
                hi_open: false,
            },
            ..self
        }
    }
    /// Numbers `> lo`.
    pub const fn above(self, lo: f64) -> Self {
        Self {
            range: Range::Float {
                lo,
                lo_open: true,
                hi: f64::INFINITY,
                hi_open: true,
            },
            ..self
        }
    }
    /// Numbers `> lo` and `<= hi`.
    pub const fn above_upto(self, lo: f64, hi: f64) -> Self {
        Self {
            range: Range::Float {
                lo,
                lo_open: true,
                hi,
                hi_open: false,
            },
            ..self
        }
    }
    /// Numbers `>= lo`.
    pub const fn at_least(self, lo: f64) -> Self {
        Self {
            range: Range::Float {
                lo,
                lo_open: false,
                hi: f64::INFINITY,
                hi_open: true,
            },
            ..self
        }
    }
    /// Any range.
    pub const fn range(self, range: Range) -> Self {
        Self { range, ..self }
    }

    /// What `describe` shows in the range column.
    pub fn range_text(&self) -> String {
        match self.ty {
            ParamType::Choice(c) => c.join("|"),
            ParamType::NumOr(w) => format!("{} | {}", w.join("|"), self.range),
            _ => self.range.to_string(),
        }
    }

    /// Checks one value's type and range; the message says what was wrong.
    pub fn check(&self, v: &Value) -> Result<(), String> {
        let bad_type = || {
            format!(
                "invalid type: {}, expected {}",
                found(v),
                self.ty.expected()
            )
        };
        let num = |x: &Value| -> Result<(), String> {
            let f = match x {
                Value::Integer(i) => *i as f64,
                Value::Float(f) => *f,
                _ => return Err(bad_type()),
            };
            if self.range.contains_f(f) {
                Ok(())
            } else {
                Err(self.out_of_range(&num_text(x)))
            }
        };
        match (self.ty, v) {
            (ParamType::Bool, Value::Boolean(_)) => Ok(()),
            (ParamType::Int, Value::Integer(_)) => num(v),
            (ParamType::Float, Value::Integer(_) | Value::Float(_)) => num(v),
            (ParamType::Str | ParamType::Path, Value::String(_)) => Ok(()),
            (ParamType::Choice(c), Value::String(s)) => {
                if c.contains(&s.as_str()) {
                    Ok(())
                } else {
                    Err(format!("must be {}, got `{s}`", or_list(c)))
                }
            }
            (ParamType::NumOr(_), Value::Integer(_) | Value::Float(_)) => num(v),
            (ParamType::NumOr(w), Value::String(s)) => {
                if w.contains(&s.as_str()) {
                    Ok(())
                } else {
                    let words: Vec<String> = w.iter().map(|w| format!("\"{w}\"")).collect();
                    let words: Vec<&str> = words.iter().map(String::as_str).collect();
                    Err(format!(
                        "must be {} or a number {}, got \"{s}\"",
                        or_list(&words),
                        self.range
                    ))
                }
            }
            (ParamType::Ints, Value::Array(a)) => a.iter().try_for_each(|x| match x {
                Value::Integer(_) => num(x),
                _ => Err(bad_type()),
            }),
            (ParamType::Floats, Value::Array(a)) => a.iter().try_for_each(num),
            (ParamType::Table, Value::Table(_)) => Ok(()),
            (ParamType::Tables, Value::Array(a)) if a.iter().all(Value::is_table) => Ok(()),
            _ => Err(bad_type()),
        }
    }

    fn out_of_range(&self, got: &str) -> String {
        let unit = if self.unit.is_empty() {
            String::new()
        } else {
            format!(" {}", self.unit)
        };
        match self.range {
            Range::Any => format!("must be a finite number, got {got}"),
            r => format!("must be {r}{unit}, got {got}"),
        }
    }
}

fn num_text(v: &Value) -> String {
    match v {
        Value::Integer(i) => i.to_string(),
        Value::Float(f) => f.to_string(),
        other => other.to_string(),
    }
}

/// How serde names a value in an `invalid type` message.
fn found(v: &Value) -> String {
    match v {
        Value::String(s) => format!("string {s:?}"),
        Value::Integer(i) => format!("integer `{i}`"),
        Value::Float(f) => format!("floating point `{f}`"),
        Value::Boolean(b) => format!("boolean `{b}`"),
        Value::Datetime(d) => format!("datetime `{d}`"),
        Value::Array(_) => "sequence".into(),
        Value::Table(_) => "map".into(),
    }
}

/// `a, b or c`.
pub fn or_list(items: &[&str]) -> String {
    match items {
        [] => String::new(),
        [one] => one.to_string(),
        [init @ .., last] => format!("{} or {last}", init.join(", ")),
    }
}

/// The typed parameters of one or more stage kinds: a struct declared
/// with [`params!`](crate::params), the one place each parameter's name,
/// Rust type, TOML type, default, range, unit and doc are written. The
/// kind validates a stage against [`KindParams::PARAMS`], reads the stage
/// into the struct ([`Params::resolve_typed`]), and `vibroscope kinds`
/// prints the same table; a recipe edits a stage through the struct's
/// typed [`Key`]s (one associated constant per field, named as the field).
pub trait KindParams: DeserializeOwned {
    /// The TOML `kind`s whose parameters these are (first: the main one).
    const KINDS: &'static [&'static str];
    /// Every parameter, in declaration order.
    const PARAMS: &'static [ParamSpec];
}

/// One parameter of the kinds whose parameters are `K`, of Rust type `T`:
/// `MagnifyParams::factor` is a `Key<MagnifyParams, f64>`. A recipe can
/// only set a parameter that exists, on a stage of a kind that has it,
/// to a value of its type.
pub struct Key<K, T> {
    pub name: &'static str,
    _of: std::marker::PhantomData<fn() -> (K, T)>,
}

impl<K, T> Clone for Key<K, T> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<K, T> Copy for Key<K, T> {}

impl<K: KindParams, T> Key<K, T> {
    pub const fn new(name: &'static str) -> Self {
        Self {
            name,
            _of: std::marker::PhantomData,
        }
    }
    /// The parameter's declaration (its default, range, unit and doc).
    pub fn spec(&self) -> &'static ParamSpec {
        // Every key is generated from a field of `K::PARAMS`.
        K::PARAMS
            .iter()
            .find(|s| s.name == self.name)
            .unwrap_or(&K::PARAMS[0])
    }
}

impl<K: KindParams, T: DeserializeOwned> Key<K, T> {
    /// The declared default (`None` for required and automatic ones).
    pub fn default_value(&self) -> Option<T> {
        default_of(K::PARAMS, self.name)
    }
}

/// The id of a stage of a kind whose parameters are `K`, in a shipped
/// pipeline (`pipelines::magnify::MAG`) or made by a recipe.
pub struct StageId<K> {
    pub id: &'static str,
    _of: std::marker::PhantomData<fn() -> K>,
}

impl<K> Clone for StageId<K> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<K> Copy for StageId<K> {}

impl<K: KindParams> StageId<K> {
    pub const fn new(id: &'static str) -> Self {
        Self {
            id,
            _of: std::marker::PhantomData,
        }
    }
}

// ------------------------------------------------------- typed edits

impl StageDecl {
    /// A new stage `id` of `K`'s main kind reading from `inputs`, without
    /// parameters.
    pub fn new_of<K: KindParams>(id: &str, inputs: &[&str], origin: Origin) -> Self {
        Self::new_kind(id, K::KINDS[0], inputs, origin)
    }

    fn new_kind(id: &str, kind: &str, inputs: &[&str], origin: Origin) -> Self {
        StageDecl {
            id: id.into(),
            kind: kind.into(),
            origin: origin.clone(),
            kind_origin: origin.clone(),
            inputs: inputs
                .iter()
                .map(|from| InputDecl {
                    from: (*from).into(),
                    capacity: None,
                    policy: None,
                    origin: origin.clone(),
                })
                .collect(),
            capacity: None,
            policy: None,
            params: Vec::new(),
        }
    }

    /// A new stage of `kind`, one of those whose parameters are `K`
    /// (`bandpass` or `bandstop` for the band's); `None` for another kind.
    pub fn new_kind_of<K: KindParams>(
        id: &str,
        kind: &str,
        inputs: &[&str],
        origin: Origin,
    ) -> Option<Self> {
        let kind = K::KINDS.iter().find(|k| **k == kind)?;
        Some(Self::new_kind(id, kind, inputs, origin))
    }

    /// The parameters set, in order, each with its origin.
    pub fn params(&self) -> &[Param] {
        &self.params
    }

    /// Unsets every parameter (the stage is about to become another kind).
    pub fn clear_params(&mut self) {
        self.params.clear();
    }

    /// Unsets `key`: its default applies.
    pub fn unset<K: KindParams, T>(&mut self, key: Key<K, T>) {
        self.params.retain(|p| p.key != key.name);
    }

    /// Whether the stage's kind has the parameters `K`.
    pub fn is<K: KindParams>(&self) -> bool {
        K::KINDS.contains(&self.kind.as_str())
    }

    /// Sets the parameter `key` to `v` (`None`: unsets it, so the default
    /// applies), remembering `origin` for error messages; refused when the
    /// stage's kind has no such parameter (a `--pipeline` file whose stage
    /// of this id is another kind). `file` names the pipeline in the error.
    pub fn set<K: KindParams, T: Serialize>(
        &mut self,
        file: &str,
        key: Key<K, T>,
        v: T,
        origin: Origin,
    ) -> Result<(), ConfigError> {
        if !self.is::<K>() {
            return Err(err(
                file,
                Some(origin),
                Some(&self.id),
                Some(key.name),
                format!(
                    "the stage is a `{}`, which has no parameter `{}` of {} (this command sets it)",
                    self.kind,
                    key.name,
                    K::KINDS.join("/")
                ),
            ));
        }
        #[derive(Serialize)]
        struct One<'a, T> {
            v: &'a T,
        }
        let value = toml::Table::try_from(One { v: &v })
            .map_err(|e| {
                err(
                    file,
                    Some(origin.clone()),
                    Some(&self.id),
                    Some(key.name),
                    format!("cannot be written as TOML: {e}"),
                )
            })?
            .remove("v");
        match value {
            Some(value) => set_param(self, key.name, value, origin),
            None => self.params.retain(|p| p.key != key.name),
        }
        Ok(())
    }

    /// The value of `key`: the one set, else the declared default; `None`
    /// when neither exists (a required or automatic parameter not set),
    /// or the stage is of another kind, or the value does not read as `T`.
    pub fn get<K: KindParams, T: DeserializeOwned>(&self, key: Key<K, T>) -> Option<T> {
        if !self.is::<K>() {
            return None;
        }
        match self.params.iter().find(|p| p.key == key.name) {
            Some(p) => T::deserialize(p.value.clone()).ok(),
            None => key.default_value(),
        }
    }
}

/// A pipeline (`file`) that lacks the stage `id` a recipe edits (a file
/// given with `--pipeline` that is not shaped like the shipped one).
pub fn no_stage(file: &str, id: &str) -> ConfigError {
    err(
        file,
        None,
        None,
        None,
        format!("the pipeline has no stage `{id}`, which this command edits"),
    )
}

impl PipelineDecl {
    fn missing(&self, id: &str) -> ConfigError {
        no_stage(&self.file, id)
    }

    /// The stage `id`.
    pub fn stage<K: KindParams>(&self, id: StageId<K>) -> Result<&StageDecl, ConfigError> {
        self.stages
            .iter()
            .find(|s| s.id == id.id)
            .ok_or_else(|| self.missing(id.id))
    }

    /// The stage `id`, to edit.
    pub fn stage_mut<K: KindParams>(
        &mut self,
        id: StageId<K>,
    ) -> Result<&mut StageDecl, ConfigError> {
        match self.stages.iter().position(|s| s.id == id.id) {
            Some(i) => Ok(&mut self.stages[i]),
            None => Err(self.missing(id.id)),
        }
    }

    /// Sets `key` of the stage `id` ([`StageDecl::set`]).
    pub fn set<K: KindParams, T: Serialize>(
        &mut self,
        id: StageId<K>,
        key: Key<K, T>,
        v: T,
        origin: Origin,
    ) -> Result<(), ConfigError> {
        let file = self.file.clone();
        self.stage_mut(id)?.set(&file, key, v, origin)
    }
}

/// Declares a stage kind's parameters once: the public struct the stage
/// reads (`serde`, unknown fields refused), its [`KindParams`] table and
/// one typed [`Key`] per field.
///
/// ```
/// use vibroscope_core::params;
/// use vibroscope_core::spec::{Def, KindParams, ParamSpec, ParamType::*};
/// params! {
///     /// `demo`'s parameters.
///     pub struct DemoParams for "demo" {
///         fps: f64 = ParamSpec::of(Float, Def::Float(2200.0))
///             .above(0.0)
///             .unit("Hz")
///             .doc("frame rate"),
///         path: String = ParamSpec::of(Path, Def::Required).doc("output file"),
///     }
/// }
/// assert_eq!(DemoParams::PARAMS[0].name, "fps");
/// assert_eq!(DemoParams::fps.default_value(), Some(2200.0));
/// ```
#[macro_export]
macro_rules! params {
    (
        $(#[$meta:meta])*
        $vis:vis struct $name:ident for $($kind:literal),+ {
            $(
                $(#[$fmeta:meta])*
                $field:ident : $ty:ty = $spec:expr
            ),* $(,)?
        }
    ) => {
        #[derive(Clone, Debug, serde::Deserialize)]
        #[serde(deny_unknown_fields)]
        $(#[$meta])*
        $vis struct $name {
            $( $(#[$fmeta])* pub $field: $ty, )*
        }
        impl $crate::spec::KindParams for $name {
            const KINDS: &'static [&'static str] = &[$($kind),+];
            const PARAMS: &'static [$crate::spec::ParamSpec] = &[
                $( $spec.named($crate::spec::unraw(stringify!($field))), )*
            ];
        }
        #[allow(non_upper_case_globals)]
        impl $name {
            $(
                #[doc = concat!("The `", stringify!($field), "` parameter.")]
                pub const $field: $crate::spec::Key<$name, $ty> =
                    $crate::spec::Key::new($crate::spec::unraw(stringify!($field)));
            )*
        }
    };
}

/// A field's name as its parameter's: `r#type` is `type`.
pub const fn unraw(s: &'static str) -> &'static str {
    match s.as_bytes() {
        [b'r', b'#', rest @ ..] => match std::str::from_utf8(rest) {
            Ok(r) => r,
            Err(_) => s,
        },
        _ => s,
    }
}

/// The value `name` defaults to, deserialized (`None` when the kind has no
/// such parameter or it has no default). For `Default` impls of
/// parameter types that are also read without [`Params::resolve`].
pub fn default_of<T: DeserializeOwned>(specs: &[ParamSpec], name: &str) -> Option<T> {
    let v = specs.iter().find(|s| s.name == name)?.default.value()?;
    T::deserialize(v).ok()
}

impl Params<'_> {
    /// [`Params::resolve`] against `K`'s own table.
    pub fn resolve_typed<K: KindParams>(&self) -> Result<K, ConfigError> {
        self.resolve(K::PARAMS)
    }

    /// Validates the stage's parameters against `specs` (unknown keys,
    /// types, ranges and choices, required fields), fills in the declared
    /// defaults and deserializes `T`. Every error names the file, line,
    /// stage, field and value.
    pub fn resolve<T: DeserializeOwned>(&self, specs: &[ParamSpec]) -> Result<T, ConfigError> {
        let mut all: Vec<Param> = Vec::with_capacity(specs.len());
        for p in &self.stage.params {
            let Some(spec) = specs.iter().find(|s| s.name == p.key) else {
                let names: Vec<String> = specs.iter().map(|s| format!("`{}`", s.name)).collect();
                let msg = if names.is_empty() {
                    format!("unknown field `{}`, there are no fields", p.key)
                } else {
                    format!(
                        "unknown field `{}`, expected one of {}",
                        p.key,
                        names.join(", ")
                    )
                };
                return Err(self.error(&p.key, msg));
            };
            spec.check(&p.value).map_err(|m| self.error(&p.key, m))?;
            all.push(p.clone());
        }
        for spec in specs {
            if self.stage.params.iter().any(|p| p.key == spec.name) {
                continue;
            }
            match spec.default {
                Def::Required => {
                    return Err(ConfigError {
                        file: self.file.to_string(),
                        origin: Some(self.stage.origin.clone()),
                        stage: Some(self.stage.id.as_str().into()),
                        field: Some(spec.name.into()),
                        message: format!("missing field `{}`", spec.name),
                    })
                }
                d => {
                    if let Some(value) = d.value() {
                        all.push(Param {
                            key: spec.name.to_string(),
                            value,
                            origin: Origin::Builtin("default".into()),
                        });
                    }
                }
            }
        }
        self.parse_list(&all)
    }
}

/// An input port: the edges a stage's `input` lists arrive here.
#[derive(Clone, Copy, Debug)]
pub struct InPort {
    pub name: &'static str,
    /// Payload types accepted.
    pub accepts: &'static [PortType],
    /// How many edges may connect.
    pub max_edges: usize,
}

impl InPort {
    /// The usual input: `in`, one edge.
    pub const fn one(accepts: &'static [PortType]) -> Self {
        Self {
            name: "in",
            accepts,
            max_edges: 1,
        }
    }
}

/// An output port's payload.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OutType {
    Fixed(PortType),
    /// Whatever arrives on the inputs (pass-through stages).
    SameAsInput,
    /// The type a `Choice` parameter of this name names (a network source
    /// says what it receives); its default when the parameter is absent.
    FromParam(&'static str),
}

/// An output port (fan-out: any number of consumers).
#[derive(Clone, Copy, Debug)]
pub struct OutPort {
    pub name: &'static str,
    pub ty: OutType,
}

impl OutPort {
    /// The usual output: `out`, of one type.
    pub const fn out(t: PortType) -> Self {
        Self {
            name: "out",
            ty: OutType::Fixed(t),
        }
    }
}

/// Sources take no input.
pub const NO_INPUTS: &[InPort] = &[];
/// Sinks give no output.
pub const NO_OUTPUTS: &[OutPort] = &[];

impl KindSpec {
    /// "source", "sink" or "stage".
    pub fn role(&self) -> &'static str {
        if self.is_source() {
            "source"
        } else if self.outputs.is_empty() {
            "sink"
        } else {
            "stage"
        }
    }

    /// One line: name, role, summary (the `vibroscope kinds` listing).
    pub fn line(&self) -> String {
        format!("{:<16} {:<7} {}", self.name, self.role(), self.summary)
    }

    /// The kind's ports and parameters as a table (`vibroscope kinds KIND`).
    pub fn describe(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "{} ({}): {}", self.name, self.role(), self.summary);
        s.push('\n');
        if self.inputs.is_empty() {
            s.push_str("inputs:  none\n");
        }
        for p in self.inputs {
            let t: Vec<String> = p.accepts.iter().map(|t| t.to_string()).collect();
            let n = if p.max_edges == 1 {
                String::new()
            } else {
                format!(" (up to {} edges)", p.max_edges)
            };
            let t = if t.is_empty() {
                "any".to_string()
            } else {
                t.join(" | ")
            };
            let _ = writeln!(s, "input:   {}: {t}{n}", p.name);
        }
        if self.outputs.is_empty() {
            s.push_str("outputs: none\n");
        }
        for p in self.outputs {
            let t = match p.ty {
                OutType::Fixed(t) => t.to_string(),
                OutType::SameAsInput => "same as input".into(),
                OutType::FromParam(name) => format!("the `{name}` parameter's type"),
            };
            let _ = writeln!(s, "output:  {}: {t}", p.name);
        }
        s.push('\n');
        if self.params.is_empty() {
            s.push_str("no parameters\n");
            return s;
        }
        let rows: Vec<[String; 6]> = self
            .params
            .iter()
            .map(|p| {
                [
                    p.name.to_string(),
                    p.ty.to_string(),
                    p.default.to_string(),
                    p.range_text(),
                    p.unit.to_string(),
                    p.doc.to_string(),
                ]
            })
            .collect();
        let head = ["name", "type", "default", "range", "unit", "doc"];
        let mut w = head.map(str::len);
        for r in &rows {
            for (i, c) in r.iter().enumerate().take(5) {
                w[i] = w[i].max(c.chars().count());
            }
        }
        let mut row = |cells: [&str; 6]| {
            let mut line = String::new();
            for (i, c) in cells.iter().enumerate() {
                if i < 5 {
                    let _ = write!(line, "{c:<0$}  ", w[i]);
                } else {
                    line.push_str(c);
                }
            }
            s.push_str(line.trim_end());
            s.push('\n');
        };
        row(head);
        for r in &rows {
            row([&r[0], &r[1], &r[2], &r[3], &r[4], &r[5]]);
        }
        s
    }
}

/// One line per kind: what `vibroscope kinds` prints.
pub fn listing(registry: &[KindSpec]) -> String {
    registry.iter().map(|k| k.line() + "\n").collect()
}

/// What a stage gives downstream.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Output {
    /// A sink.
    None,
    Fixed(PortType),
    /// Whatever its input carries (pass-through stages).
    SameAsInput,
    /// The type named by this parameter ([`OutType::FromParam`]).
    FromParam(&'static str),
}

/// A stage kind in the registry: the name used as `kind` in TOML, its
/// named and typed ports, and its parameters declared as data (see
/// this module). Copied freely: a registry is assembled from the lists
/// of several crates.
#[derive(Clone, Copy)]
pub struct KindSpec {
    pub name: &'static str,
    pub summary: &'static str,
    /// Input ports; empty for sources. A stage's `input` edges all arrive
    /// on its (single) input port.
    pub inputs: &'static [InPort],
    /// Output ports; empty for sinks.
    pub outputs: &'static [OutPort],
    /// Every parameter: name, type, default, range, unit, doc.
    pub params: &'static [ParamSpec],
    /// Validates the parameters ([`Params::resolve`] against `params`,
    /// then any checks across fields); opens nothing.
    pub plan: fn(&Params<'_>) -> Result<Box<dyn Plan>, ConfigError>,
}

impl KindSpec {
    pub fn is_source(&self) -> bool {
        self.inputs.is_empty()
    }

    /// Payload types accepted on the input port.
    pub fn accepts(&self) -> &'static [PortType] {
        self.inputs.first().map_or(&[], |p| p.accepts)
    }

    /// Edges the input port takes.
    pub fn max_inputs(&self) -> usize {
        self.inputs.iter().map(|p| p.max_edges).sum()
    }

    /// What the stage gives downstream.
    pub fn output(&self) -> Output {
        match self.outputs.first().map(|p| p.ty) {
            None => Output::None,
            Some(OutType::Fixed(t)) => Output::Fixed(t),
            Some(OutType::SameAsInput) => Output::SameAsInput,
            Some(OutType::FromParam(n)) => Output::FromParam(n),
        }
    }
}

/// Everything a validated stage needs to become a running [`Node`].
pub struct BuildCtx {
    /// The stage's id in the pipeline.
    pub id: String,
    /// Frame buffers a source should put in its pool.
    pub pool_frames: usize,
    /// Items this stage's output can have in flight downstream at once:
    /// on every edge leaving it, the ring's capacity plus what the
    /// consumer holds while working (a stage that recycles its output
    /// buffers, as `pyramid` does, never has more than this plus its own
    /// workers' outstanding).
    pub held_downstream: usize,
    /// Types arriving on each input port.
    pub input_types: Vec<PortType>,
    /// The graph has a live source: sinks that pace themselves (a speaker)
    /// drop rather than hold up the stream.
    pub live: bool,
    /// Who watches the run (the `tap` stages publish to it); none for a
    /// plain run.
    pub observer: Option<std::sync::Arc<crate::observe::Observer>>,
    /// Where a stage that works on threads of its own adds the time they
    /// spend working (ns): its busy time (`--stats`' `us/item`, the
    /// studio's `busy`) is the larger of this and its own thread's.
    pub worker_busy_ns: std::sync::Arc<std::sync::atomic::AtomicU64>,
}

/// A stage whose parameters are valid; `build` opens files and devices.
pub trait Plan: Send {
    fn build(self: Box<Self>, ctx: &BuildCtx) -> Result<Node, StageError>;
    /// Live sources (cameras, real-time simulation) pace themselves.
    fn is_live(&self) -> bool {
        false
    }
    /// Frames this stage keeps beyond the one it is processing.
    fn frames_held(&self) -> usize {
        0
    }
}
