//! Pipeline files, phase one: TOML to declarations, with a line for every
//! value so that errors can point at it.
//!
//! ```toml
//! [pipeline]
//! name = "example"
//! description = "synthetic tone to a WAV file"
//!
//! [[stage]]
//! id = "cam"              # unique name, used by `input` and `--set cam.KEY=VALUE`
//! kind = "synthetic"      # see `vibroscope kinds`
//! fps = 2200.0            # ...parameters of the kind
//!
//! [[stage]]
//! id = "out"
//! kind = "wav"
//! input = "cam"           # or ["a", "b"], or [{ from = "a", capacity = 4, policy = "block" }]
//! capacity = 16           # ring slots on each input edge (default 16)
//! policy = "block"        # or "drop_oldest" (default: drop_oldest after a live source)
//! path = "out.wav"
//! ```
//!
//! Parameters are deserialized into each kind's own struct by
//! [`Params::parse`], which knows which key it is reading when serde
//! complains, so `unknown field`, `invalid type` and range errors all name
//! the file, line, stage and field.

use serde::de::{self, DeserializeSeed, IntoDeserializer, MapAccess, Visitor};
use serde::Deserialize;
use std::cell::Cell;
use std::fmt;
use toml::{Spanned, Value};

/// Where a value came from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Origin {
    /// A line (1-based) of the pipeline file.
    Line(usize),
    /// A `--set` override on the command line.
    Set(String),
    /// Built in (defaults, `--replay`).
    Builtin(String),
}

/// A configuration error; exit status 2.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ConfigError {
    pub file: String,
    pub origin: Option<Origin>,
    pub stage: Option<Box<str>>,
    pub field: Option<Box<str>>,
    pub message: String,
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file)?;
        match &self.origin {
            Some(Origin::Line(l)) => write!(f, ":{l}")?,
            // A command-line flag that stands for a setting names itself.
            Some(Origin::Set(s)) if s.starts_with('-') => write!(f, " ({s})")?,
            Some(Origin::Set(s)) => write!(f, " (--set {s})")?,
            Some(Origin::Builtin(s)) => write!(f, " ({s})")?,
            None => {}
        }
        f.write_str(": ")?;
        if let Some(s) = &self.stage {
            write!(f, "stage `{s}`: ")?;
        }
        if let Some(k) = &self.field {
            write!(f, "field `{k}`: ")?;
        }
        f.write_str(&self.message)
    }
}

impl std::error::Error for ConfigError {}

/// A parameter value with its origin.
#[derive(Clone, Debug)]
pub struct Param {
    pub key: String,
    pub value: Value,
    pub origin: Origin,
}

/// One `input` entry.
#[derive(Clone, Debug)]
pub struct InputDecl {
    pub from: String,
    pub capacity: Option<i64>,
    pub policy: Option<String>,
    pub origin: Origin,
}

/// One `[[stage]]` table.
#[derive(Clone, Debug)]
pub struct StageDecl {
    pub id: String,
    pub kind: String,
    /// Where the table is (its `id`, else `kind`, else its header).
    pub origin: Origin,
    pub kind_origin: Origin,
    pub inputs: Vec<InputDecl>,
    pub capacity: Option<(i64, Origin)>,
    pub policy: Option<(String, Origin)>,
    /// Set by the TOML reader, `--set` and the typed keys only
    /// ([`StageDecl::set`]): no other code can address a parameter by a
    /// string. Read with [`StageDecl::params`].
    pub(crate) params: Vec<Param>,
}

/// A parsed pipeline file.
#[derive(Clone, Debug)]
pub struct PipelineDecl {
    /// How errors name the file (its path, or `builtin:NAME`).
    pub file: String,
    pub name: String,
    pub description: String,
    pub stages: Vec<StageDecl>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawFile {
    pipeline: Option<RawMeta>,
    #[serde(default)]
    stage: Vec<Spanned<RawStage>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMeta {
    name: Option<String>,
    description: Option<String>,
}

struct RawStage {
    entries: Vec<(String, Spanned<Value>)>,
}

impl<'de> Deserialize<'de> for RawStage {
    fn deserialize<D: de::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = RawStage;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a [[stage]] table")
            }
            fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<RawStage, A::Error> {
                let mut entries = Vec::new();
                while let Some(k) = map.next_key::<String>()? {
                    let v = map.next_value::<Spanned<Value>>()?;
                    entries.push((k, v));
                }
                Ok(RawStage { entries })
            }
        }
        d.deserialize_map(V)
    }
}

/// 1-based line of byte offset `pos` in `text`.
pub fn line_of(text: &str, pos: usize) -> usize {
    let pos = pos.min(text.len());
    text.as_bytes()[..pos]
        .iter()
        .filter(|&&b| b == b'\n')
        .count()
        + 1
}

pub(crate) fn err(
    file: &str,
    origin: Option<Origin>,
    stage: Option<&str>,
    field: Option<&str>,
    msg: impl Into<String>,
) -> ConfigError {
    ConfigError {
        file: file.to_string(),
        origin,
        stage: stage.map(Into::into),
        field: field.map(Into::into),
        message: msg.into(),
    }
}

/// A TOML syntax error in `text` (the file `file`): its line, the key on
/// that line as the field, and a message even where the parser gives none
/// (a file ending in `key =`).
pub fn toml_error(file: &str, text: &str, e: &toml::de::Error) -> ConfigError {
    let at = e.span().map(|s| s.start.min(text.len()));
    let origin = at.map(|p| Origin::Line(line_of(text, p)));
    let entry = at.and_then(|p| {
        let start = text[..p].rfind('\n').map_or(0, |i| i + 1);
        let line = text[start..].lines().next().unwrap_or("");
        let (k, v) = line.split_once('=')?;
        let k = k.trim();
        let bare = !k.is_empty()
            && k.chars()
                .all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.'));
        bare.then(|| (k.to_string(), v.trim().is_empty()))
    });
    let mut message = e.message().trim().to_string();
    if message.is_empty() || entry.as_ref().is_some_and(|(_, empty)| *empty) {
        message = match &entry {
            Some(_) => "the value is missing (nothing after `=`)".into(),
            None => "the file ends in the middle of an entry".into(),
        };
    }
    let key = entry.map(|(k, _)| k);
    err(file, origin, None, key.as_deref(), message)
}

/// Parses pipeline text. `file` is how errors name it.
pub fn parse(file: &str, text: &str) -> Result<PipelineDecl, ConfigError> {
    let raw: RawFile = toml::from_str(text).map_err(|e| toml_error(file, text, &e))?;
    let meta = raw.pipeline.unwrap_or(RawMeta {
        name: None,
        description: None,
    });
    let mut stages = Vec::new();
    for st in raw.stage {
        let table_origin = Origin::Line(line_of(text, st.span().start));
        let st = st.into_inner();
        let at = |v: &Spanned<Value>| Origin::Line(line_of(text, v.span().start));
        let mut id = None;
        let mut kind = None;
        let mut inputs = Vec::new();
        let mut capacity = None;
        let mut policy = None;
        let mut params = Vec::new();
        for (k, v) in &st.entries {
            let o = at(v);
            match k.as_str() {
                "id" => match v.get_ref() {
                    Value::String(s) => id = Some((s.clone(), o)),
                    other => {
                        return Err(err(
                            file,
                            Some(o),
                            None,
                            Some("id"),
                            format!("expected a string, found {}", other.type_str()),
                        ))
                    }
                },
                "kind" => match v.get_ref() {
                    Value::String(s) => kind = Some((s.clone(), o)),
                    other => {
                        return Err(err(
                            file,
                            Some(o),
                            None,
                            Some("kind"),
                            format!("expected a string, found {}", other.type_str()),
                        ))
                    }
                },
                _ => {}
            }
        }
        let (id, origin) = id.ok_or_else(|| {
            err(
                file,
                Some(table_origin.clone()),
                None,
                Some("id"),
                "every [[stage]] needs an `id`",
            )
        })?;
        let (kind, kind_origin) = kind.ok_or_else(|| {
            err(
                file,
                Some(table_origin.clone()),
                Some(&id),
                Some("kind"),
                "missing `kind`",
            )
        })?;
        for (k, v) in st.entries {
            let o = at(&v);
            match k.as_str() {
                "id" | "kind" => {}
                "input" => inputs = parse_inputs(file, &id, v.get_ref(), &o)?,
                "capacity" => match v.get_ref() {
                    Value::Integer(n) => capacity = Some((*n, o)),
                    other => {
                        return Err(err(
                            file,
                            Some(o),
                            Some(&id),
                            Some("capacity"),
                            format!("expected an integer, found {}", other.type_str()),
                        ))
                    }
                },
                "policy" => match v.get_ref() {
                    Value::String(s) => policy = Some((s.clone(), o)),
                    other => {
                        return Err(err(
                            file,
                            Some(o),
                            Some(&id),
                            Some("policy"),
                            format!(
                                "expected \"block\" or \"drop_oldest\", found {}",
                                other.type_str()
                            ),
                        ))
                    }
                },
                _ => params.push(Param {
                    key: k,
                    value: v.into_inner(),
                    origin: o,
                }),
            }
        }
        stages.push(StageDecl {
            id,
            kind,
            origin,
            kind_origin,
            inputs,
            capacity,
            policy,
            params,
        });
    }
    Ok(PipelineDecl {
        file: file.to_string(),
        name: meta.name.unwrap_or_default(),
        description: meta.description.unwrap_or_default(),
        stages,
    })
}

fn parse_inputs(
    file: &str,
    id: &str,
    v: &Value,
    o: &Origin,
) -> Result<Vec<InputDecl>, ConfigError> {
    let bad = |m: String| err(file, Some(o.clone()), Some(id), Some("input"), m);
    let one = |v: &Value| -> Result<InputDecl, ConfigError> {
        match v {
            Value::String(s) => Ok(InputDecl {
                from: s.clone(),
                capacity: None,
                policy: None,
                origin: o.clone(),
            }),
            Value::Table(t) => {
                let mut d = InputDecl {
                    from: String::new(),
                    capacity: None,
                    policy: None,
                    origin: o.clone(),
                };
                for (k, v) in t {
                    match (k.as_str(), v) {
                        ("from", Value::String(s)) => d.from = s.clone(),
                        ("capacity", Value::Integer(n)) => d.capacity = Some(*n),
                        ("policy", Value::String(s)) => d.policy = Some(s.clone()),
                        ("from" | "capacity" | "policy", v) => {
                            return Err(bad(format!("`{k}` has the wrong type ({})", v.type_str())))
                        }
                        _ => return Err(bad(format!("unknown key `{k}` in an input table, expected `from`, `capacity` or `policy`"))),
                    }
                }
                if d.from.is_empty() {
                    return Err(bad("an input table needs `from = \"STAGE_ID\"`".into()));
                }
                Ok(d)
            }
            other => Err(bad(format!(
                "expected a stage id or a table, found {}",
                other.type_str()
            ))),
        }
    };
    match v {
        Value::Array(a) => a.iter().map(one).collect(),
        v => Ok(vec![one(v)?]),
    }
}

/// Applies `--set STAGE.KEY=VALUE`. VALUE is read as a TOML value when it
/// parses as one (`2200`, `true`, `[1, 2]`, `"x"`), else as a plain string.
pub fn apply_set(p: &mut PipelineDecl, spec: &str) -> Result<(), ConfigError> {
    let origin = Origin::Set(spec.to_string());
    let bad = |stage: Option<&str>, field: Option<&str>, m: String| {
        err(&p.file, Some(origin.clone()), stage, field, m)
    };
    let (lhs, rhs) = spec
        .split_once('=')
        .ok_or_else(|| bad(None, None, "expected STAGE.KEY=VALUE".into()))?;
    let (sid, key) = lhs
        .trim()
        .split_once('.')
        .ok_or_else(|| bad(None, None, format!("`{lhs}` should be STAGE.KEY")))?;
    let value = parse_value(rhs.trim());
    let ids: Vec<String> = p.stages.iter().map(|s| s.id.clone()).collect();
    let st = p.stages.iter_mut().find(|s| s.id == sid).ok_or_else(|| {
        bad(
            Some(sid),
            None,
            format!("no stage with this id (stages: {})", ids.join(", ")),
        )
    })?;
    match key {
        "id" => {
            return Err(bad(
                Some(sid),
                Some("id"),
                "cannot be changed with --set".into(),
            ))
        }
        "kind" => match value {
            Value::String(s) => {
                st.kind = s;
                st.kind_origin = origin;
            }
            v => {
                return Err(bad(
                    Some(sid),
                    Some("kind"),
                    format!("expected a string, found {}", v.type_str()),
                ))
            }
        },
        "input" => st.inputs = parse_inputs(&p.file, sid, &value, &origin)?,
        "capacity" => match value {
            Value::Integer(n) => st.capacity = Some((n, origin)),
            v => {
                return Err(bad(
                    Some(sid),
                    Some("capacity"),
                    format!("expected an integer, found {}", v.type_str()),
                ))
            }
        },
        "policy" => match value {
            Value::String(s) => st.policy = Some((s, origin)),
            v => {
                return Err(bad(
                    Some(sid),
                    Some("policy"),
                    format!("expected a string, found {}", v.type_str()),
                ))
            }
        },
        _ => set_param(st, key, value, origin),
    }
    Ok(())
}

/// Reads a TOML table into the stage's parameters (a scene file: the
/// `synthetic` source's parameters at its top level), replacing any it
/// had; `origin` says where each key was written.
pub fn read_table(st: &mut StageDecl, table: &toml::Table, origin: impl Fn(&str) -> Origin) {
    st.params.clear();
    for (k, v) in table {
        set_param(st, k, v.clone(), origin(k));
    }
}

/// Sets or replaces a parameter (the TOML reader's and `--set`'s; recipes
/// set parameters through their typed keys, [`StageDecl::set`]).
pub(crate) fn set_param(st: &mut StageDecl, key: &str, value: Value, origin: Origin) {
    match st.params.iter_mut().find(|p| p.key == key) {
        Some(p) => {
            p.value = value;
            p.origin = origin;
        }
        None => st.params.push(Param {
            key: key.to_string(),
            value,
            origin,
        }),
    }
}

pub(crate) fn parse_value(s: &str) -> Value {
    #[derive(Deserialize)]
    struct W {
        v: Value,
    }
    match toml::from_str::<W>(&format!("v = {s}")) {
        Ok(w) => w.v,
        Err(_) => Value::String(s.to_string()),
    }
}

/// The parameters of one stage, as its kind's builder sees them.
pub struct Params<'a> {
    pub file: &'a str,
    pub stage: &'a StageDecl,
}

impl<'a> Params<'a> {
    /// Deserializes the parameters into `T` (use `#[serde(deny_unknown_fields)]`).
    pub fn parse<T: de::DeserializeOwned>(&self) -> Result<T, ConfigError> {
        self.parse_list(&self.stage.params)
    }

    /// Deserializes `params` (the stage's, with defaults added) into `T`.
    pub(crate) fn parse_list<T: de::DeserializeOwned>(
        &self,
        params: &[Param],
    ) -> Result<T, ConfigError> {
        let current = Cell::new(None);
        let de = ParamsDe {
            params,
            current: &current,
        };
        T::deserialize(de).map_err(|e: ParamError| {
            let (field, origin) = match current.get() {
                Some(i) => {
                    let p = &params[i];
                    (Some(p.key.as_str()), p.origin.clone())
                }
                None => (None, self.stage.origin.clone()),
            };
            err(self.file, Some(origin), Some(&self.stage.id), field, e.0)
        })
    }

    /// An error about `field` (a range check after parsing, say).
    pub fn error(&self, field: &str, msg: impl Into<String>) -> ConfigError {
        let origin = self
            .stage
            .params
            .iter()
            .find(|p| p.key == field)
            .map(|p| p.origin.clone())
            .unwrap_or_else(|| self.stage.origin.clone());
        err(
            self.file,
            Some(origin),
            Some(&self.stage.id),
            Some(field),
            msg,
        )
    }
}

#[derive(Debug)]
struct ParamError(String);

impl fmt::Display for ParamError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}
impl std::error::Error for ParamError {}
impl de::Error for ParamError {
    fn custom<T: fmt::Display>(msg: T) -> Self {
        ParamError(msg.to_string())
    }
}

struct ParamsDe<'a> {
    params: &'a [Param],
    current: &'a Cell<Option<usize>>,
}

impl<'de> de::Deserializer<'de> for ParamsDe<'_> {
    type Error = ParamError;
    fn deserialize_any<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, ParamError> {
        visitor.visit_map(ParamsMap {
            params: self.params,
            next: 0,
            current: self.current,
        })
    }
    serde::forward_to_deserialize_any! {
        bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string
        bytes byte_buf option unit unit_struct newtype_struct seq tuple
        tuple_struct map struct enum identifier ignored_any
    }
}

struct ParamsMap<'a> {
    params: &'a [Param],
    next: usize,
    current: &'a Cell<Option<usize>>,
}

impl<'de> MapAccess<'de> for ParamsMap<'_> {
    type Error = ParamError;
    fn next_key_seed<K: DeserializeSeed<'de>>(
        &mut self,
        seed: K,
    ) -> Result<Option<K::Value>, ParamError> {
        let Some(p) = self.params.get(self.next) else {
            self.current.set(None);
            return Ok(None);
        };
        self.current.set(Some(self.next));
        let key: de::value::StrDeserializer<'_, ParamError> = p.key.as_str().into_deserializer();
        seed.deserialize(key).map(Some)
    }
    fn next_value_seed<V: DeserializeSeed<'de>>(
        &mut self,
        seed: V,
    ) -> Result<V::Value, ParamError> {
        let i = self.next;
        self.next += 1;
        let v = self.params[i].value.clone();
        seed.deserialize(v)
            .map_err(|e| ParamError(e.message().trim().to_string()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Deserialize, Debug)]
    #[serde(deny_unknown_fields)]
    struct P {
        fps: f64,
        #[serde(default)]
        #[allow(dead_code)]
        seed: u64,
    }

    const TEXT: &str = "[pipeline]\nname = \"t\"\n\n[[stage]]\nid = \"a\"\nkind = \"k\"\nfps = 10.0\nfsp = 3\n\n[[stage]]\nid = \"b\"\nkind = \"k\"\ninput = \"a\"\nfps = \"fast\"\n";

    #[test]
    fn unknown_and_mistyped_fields_name_the_line() {
        let p = parse("x.toml", TEXT).unwrap();
        let e = Params {
            file: "x.toml",
            stage: &p.stages[0],
        }
        .parse::<P>()
        .unwrap_err();
        assert_eq!(e.origin, Some(Origin::Line(8)), "{e}");
        assert_eq!(e.field.as_deref(), Some("fsp"));
        assert!(e.to_string().contains("unknown field `fsp`"), "{e}");
        let e = Params {
            file: "x.toml",
            stage: &p.stages[1],
        }
        .parse::<P>()
        .unwrap_err();
        assert_eq!(e.origin, Some(Origin::Line(14)), "{e}");
        assert_eq!(e.field.as_deref(), Some("fps"));
    }

    #[test]
    fn missing_field_points_at_the_stage() {
        let p = parse("x.toml", "[[stage]]\nid = \"a\"\nkind = \"k\"\n").unwrap();
        let e = Params {
            file: "x.toml",
            stage: &p.stages[0],
        }
        .parse::<P>()
        .unwrap_err();
        assert_eq!(e.origin, Some(Origin::Line(2)));
        assert!(e.to_string().contains("missing field `fps`"), "{e}");
    }

    #[test]
    fn set_overrides_and_types_values() {
        let mut p = parse("x.toml", TEXT).unwrap();
        apply_set(&mut p, "b.fps=600").unwrap();
        apply_set(&mut p, "a.fsp=").unwrap_or(());
        let v: P = Params {
            file: "x.toml",
            stage: &p.stages[1],
        }
        .parse()
        .unwrap();
        assert_eq!(v.fps, 600.0);
        assert!(apply_set(&mut p, "zz.fps=1")
            .unwrap_err()
            .to_string()
            .contains("no stage"));
        assert!(apply_set(&mut p, "nodot=1").is_err());
    }

    #[test]
    fn syntax_errors_carry_a_line() {
        let e = parse("x.toml", "[[stage]]\nid = \"a\"\nkind = \n").unwrap_err();
        assert_eq!(e.origin, Some(Origin::Line(3)), "{e}");
        let e = parse("x.toml", "[pipelin]\nname = \"a\"\n").unwrap_err();
        assert!(e.message.contains("unknown field"), "{e}");
    }
}
