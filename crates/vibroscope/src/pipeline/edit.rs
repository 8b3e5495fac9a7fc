//! Typed edits of a pipeline: a parameter of a shipped stage by its typed
//! id and key, new stages, rewiring, and the errors that name the option
//! that asked.

use crate::engine::config::{InputDecl, Origin, PipelineDecl, StageDecl};
use crate::engine::spec::{Key, KindParams, StageId};
use crate::error::{Error, Result};
/// A value set by an option of a recipe (errors name the option).
pub fn by(option: &str) -> Origin {
    Origin::Set(option.to_string())
}

/// The stage `id` of `decl` (an error names the pipeline when it lacks it).
pub fn stage_mut<'a>(decl: &'a mut PipelineDecl, id: &str) -> Result<&'a mut StageDecl> {
    let file = decl.file.clone();
    decl.stages
        .iter_mut()
        .find(|s| s.id == id)
        .ok_or_else(|| no_stage(&file, id))
}

/// Position of stage `id`.
pub fn position(decl: &PipelineDecl, id: &str) -> Result<usize> {
    decl.stages
        .iter()
        .position(|s| s.id == id)
        .ok_or_else(|| no_stage(&decl.file, id))
}

/// A pipeline that lacks a stage a recipe edits (a pipeline file given
/// with `--pipeline` that is not shaped like the shipped one).
pub fn no_stage(file: &str, id: &str) -> Error {
    Error::Config(crate::engine::spec::no_stage(file, id))
}

/// A count as the TOML integer a parameter holds it in (at most
/// `i64::MAX`).
pub fn count(n: usize) -> usize {
    n.min(i64::MAX as usize)
}

/// Sets the parameter `key` of the shipped stage `id` to `v` (`None`
/// unsets an optional one): the stage, the parameter and the value's type
/// are checked by the compiler; a `--pipeline` file whose stage of that id
/// is another kind is an error naming it.
pub fn set<K: KindParams, T: serde::Serialize>(
    decl: &mut PipelineDecl,
    id: StageId<K>,
    key: Key<K, T>,
    v: T,
    origin: Origin,
) -> Result<()> {
    Ok(decl.set(id, key, v, origin)?)
}

/// Sets the parameter `key` of `st`, a stage this recipe made.
pub fn put<K: KindParams, T: serde::Serialize>(
    st: &mut StageDecl,
    key: Key<K, T>,
    v: T,
    origin: Origin,
) -> Result<()> {
    Ok(st.set("vibroscope", key, v, origin)?)
}

/// A new stage `id` of `K`'s kind reading from `inputs`, without parameters.
pub fn new_stage<K: KindParams>(id: &str, inputs: &[&str], origin: Origin) -> StageDecl {
    StageDecl::new_of::<K>(id, inputs, origin)
}

/// An empty pipeline named `name`.
pub fn empty(name: &str, description: &str) -> PipelineDecl {
    PipelineDecl {
        file: format!("vibroscope {name}"),
        name: name.into(),
        description: description.into(),
        stages: Vec::new(),
    }
}

/// Every stage reading from `from` reads from `to` instead.
pub fn rewire(decl: &mut PipelineDecl, consumer: &str, to: &str) -> Result<()> {
    for inp in &mut stage_mut(decl, consumer)?.inputs {
        inp.from = to.into();
    }
    Ok(())
}

/// Inserts `st` (its input and id already set) just before the stage
/// `consumer`: it reads what `consumer` read, and `consumer` reads `st`.
pub fn insert_before(decl: &mut PipelineDecl, consumer: &str, mut st: StageDecl) -> Result<()> {
    let at = position(decl, consumer)?;
    let inputs = std::mem::take(&mut decl.stages[at].inputs);
    st.inputs = inputs
        .into_iter()
        .map(|mut i| {
            i.origin = st.origin.clone();
            i
        })
        .collect();
    let id = st.id.clone();
    decl.stages.insert(at, st);
    decl.stages[at + 1].inputs = vec![InputDecl {
        from: id,
        capacity: None,
        policy: None,
        origin: decl.stages[at].origin.clone(),
    }];
    Ok(())
}
