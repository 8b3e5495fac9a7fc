//! Pipeline files, phase two: the declarations checked as a graph. Every
//! stage's kind exists, its parameters parse and are in range, every input
//! names a stage, there is no cycle, and every edge joins ports of one type.

use super::config::{ConfigError, Origin, Params, PipelineDecl, StageDecl};
use super::edge::Policy;
use super::item::PortType;
pub use super::spec::{BuildCtx, KindSpec, Output, Plan};
use std::collections::HashMap;

pub struct ResolvedInput {
    /// Index into [`Graph::nodes`] of the producer.
    pub from: usize,
    pub capacity: usize,
    pub policy: Policy,
    pub port_type: PortType,
}

pub struct GraphNode {
    pub id: String,
    pub kind: &'static KindSpec,
    pub plan: Box<dyn Plan>,
    pub inputs: Vec<ResolvedInput>,
    pub output: Option<PortType>,
}

/// A validated pipeline, nodes in topological order.
pub struct Graph {
    pub file: String,
    pub name: String,
    pub nodes: Vec<GraphNode>,
}

impl Graph {
    /// Whether any source paces itself in real time (a camera, a live
    /// simulation); such runs report capture-to-sink latency.
    pub fn is_live(&self) -> bool {
        self.nodes.iter().any(|n| n.plan.is_live())
    }
}

pub const DEFAULT_CAPACITY: usize = 16;
pub const MAX_CAPACITY: i64 = 1 << 16;

fn cerr(
    file: &str,
    origin: &Origin,
    stage: &str,
    field: Option<&str>,
    msg: impl Into<String>,
) -> ConfigError {
    ConfigError {
        file: file.to_string(),
        origin: Some(origin.clone()),
        stage: Some(stage.into()),
        field: field.map(Into::into),
        message: msg.into(),
    }
}

/// Checks a parsed pipeline against `registry`.
pub fn validate(decl: &PipelineDecl, registry: &'static [KindSpec]) -> Result<Graph, ConfigError> {
    let file = decl.file.as_str();
    if decl.stages.is_empty() {
        return Err(ConfigError {
            file: file.to_string(),
            origin: None,
            stage: None,
            field: None,
            message: "the pipeline has no [[stage]]".into(),
        });
    }
    let mut index: HashMap<&str, usize> = HashMap::new();
    for (i, s) in decl.stages.iter().enumerate() {
        if s.id.is_empty()
            || !s
                .id
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
        {
            return Err(cerr(
                file,
                &s.origin,
                &s.id,
                Some("id"),
                "ids use letters, digits, `_` and `-`",
            ));
        }
        if let Some(&j) = index.get(s.id.as_str()) {
            let first = match &decl.stages[j].origin {
                Origin::Line(l) => format!(" (first at line {l})"),
                _ => String::new(),
            };
            return Err(cerr(
                file,
                &s.origin,
                &s.id,
                Some("id"),
                format!("duplicate stage id{first}"),
            ));
        }
        index.insert(s.id.as_str(), i);
    }
    // Kinds and parameters.
    let mut kinds = Vec::with_capacity(decl.stages.len());
    let mut plans = Vec::with_capacity(decl.stages.len());
    for s in &decl.stages {
        let kind = registry.iter().find(|k| k.name == s.kind).ok_or_else(|| {
            let names: Vec<&str> = registry.iter().map(|k| k.name).collect();
            cerr(
                file,
                &s.kind_origin,
                &s.id,
                Some("kind"),
                format!("unknown kind `{}` (known: {})", s.kind, names.join(", ")),
            )
        })?;
        kinds.push(kind);
        plans.push(Some((kind.plan)(&Params { file, stage: s })?));
    }
    // Inputs exist and arities fit.
    let mut preds: Vec<Vec<usize>> = Vec::with_capacity(decl.stages.len());
    for (s, kind) in decl.stages.iter().zip(&kinds) {
        if kind.is_source() && !s.inputs.is_empty() {
            return Err(cerr(
                file,
                &s.inputs[0].origin,
                &s.id,
                Some("input"),
                format!("a `{}` stage is a source and takes no input", kind.name),
            ));
        }
        if !kind.is_source() && s.inputs.is_empty() {
            return Err(cerr(
                file,
                &s.origin,
                &s.id,
                Some("input"),
                format!("a `{}` stage needs an `input`", kind.name),
            ));
        }
        if s.inputs.len() > kind.max_inputs() {
            return Err(cerr(
                file,
                &s.inputs[0].origin,
                &s.id,
                Some("input"),
                format!(
                    "a `{}` stage takes at most {} input(s), got {}",
                    kind.name,
                    kind.max_inputs(),
                    s.inputs.len()
                ),
            ));
        }
        let mut p = Vec::new();
        for inp in &s.inputs {
            let j = *index.get(inp.from.as_str()).ok_or_else(|| {
                cerr(
                    file,
                    &inp.origin,
                    &s.id,
                    Some("input"),
                    format!("unknown input id `{}`", inp.from),
                )
            })?;
            if kinds[j].output() == Output::None {
                return Err(cerr(
                    file,
                    &inp.origin,
                    &s.id,
                    Some("input"),
                    format!(
                        "`{}` is a `{}` sink and has no output",
                        inp.from, kinds[j].name
                    ),
                ));
            }
            p.push(j);
        }
        preds.push(p);
    }
    let order = topo_order(&preds).map_err(|i| {
        let s = &decl.stages[i];
        cerr(
            file,
            &s.origin,
            &s.id,
            Some("input"),
            "the inputs form a cycle through this stage",
        )
    })?;
    // Types, in topological order, and edge settings.
    let live: Vec<bool> = plans
        .iter()
        .map(|p| p.as_ref().is_some_and(|p| p.is_live()))
        .collect();
    let mut out_type: Vec<Option<PortType>> = vec![None; decl.stages.len()];
    let mut new_index = vec![0usize; decl.stages.len()];
    let mut nodes = Vec::with_capacity(decl.stages.len());
    for &i in &order {
        let s = &decl.stages[i];
        let kind = kinds[i];
        let mut inputs = Vec::new();
        for (inp, &j) in s.inputs.iter().zip(&preds[i]) {
            let Some(t) = out_type[j] else {
                return Err(cerr(
                    file,
                    &inp.origin,
                    &s.id,
                    Some("input"),
                    format!("`{}` has no output", inp.from),
                ));
            };
            if !kind.accepts().contains(&t) {
                let acc: Vec<String> = kind.accepts().iter().map(|t| t.to_string()).collect();
                let port = kind.inputs.first().map_or("in", |p| p.name);
                return Err(cerr(
                    file,
                    &inp.origin,
                    &s.id,
                    Some("input"),
                    format!(
                        "`{}` gives {t}, but a `{}` stage takes {} on its port `{port}`",
                        inp.from,
                        kind.name,
                        acc.join(" or ")
                    ),
                ));
            }
            let (capacity, policy) =
                edge_settings(file, s, inp.capacity, inp.policy.as_deref(), live[j])?;
            inputs.push(ResolvedInput {
                from: new_index[j],
                capacity,
                policy,
                port_type: t,
            });
        }
        out_type[i] = match kind.output() {
            Output::None => None,
            Output::Fixed(t) => Some(t),
            Output::SameAsInput => inputs.first().map(|r| r.port_type),
            Output::FromParam(name) => {
                let given = s.params.iter().find(|q| q.key == name).map(|q| &q.value);
                let default = kind
                    .params
                    .iter()
                    .find(|q| q.name == name)
                    .and_then(|q| q.default.value());
                let text = given.cloned().or(default);
                let t = text
                    .as_ref()
                    .and_then(|v| v.as_str())
                    .and_then(PortType::from_name);
                if t.is_none() {
                    return Err(cerr(
                        file,
                        &s.origin,
                        &s.id,
                        Some(name),
                        "must name an edge type: frames, samples, audio, spectrum or peaks",
                    ));
                }
                t
            }
        };
        if kind.output() == Output::SameAsInput
            && inputs.iter().any(|r| Some(r.port_type) != out_type[i])
        {
            return Err(cerr(
                file,
                &s.origin,
                &s.id,
                Some("input"),
                "all inputs of a pass-through stage must carry one type",
            ));
        }
        new_index[i] = nodes.len();
        let Some(plan) = plans[i].take() else {
            return Err(cerr(
                file,
                &s.origin,
                &s.id,
                None,
                "internal: stage planned twice",
            ));
        };
        nodes.push(GraphNode {
            id: s.id.clone(),
            kind,
            plan,
            inputs,
            output: out_type[i],
        });
    }
    Ok(Graph {
        file: file.to_string(),
        name: decl.name.clone(),
        nodes,
    })
}

fn edge_settings(
    file: &str,
    s: &StageDecl,
    cap: Option<i64>,
    pol: Option<&str>,
    producer_live: bool,
) -> Result<(usize, Policy), ConfigError> {
    let (cap, cap_origin) = match (cap, &s.capacity) {
        (Some(c), _) => (
            Some(c),
            s.inputs
                .first()
                .map(|i| i.origin.clone())
                .unwrap_or(s.origin.clone()),
        ),
        (None, Some((c, o))) => (Some(*c), o.clone()),
        (None, None) => (None, s.origin.clone()),
    };
    let capacity = match cap {
        None => DEFAULT_CAPACITY,
        Some(c) if (1..=MAX_CAPACITY).contains(&c) => c as usize,
        Some(c) => {
            return Err(cerr(
                file,
                &cap_origin,
                &s.id,
                Some("capacity"),
                format!("must be between 1 and {MAX_CAPACITY}, got {c}"),
            ))
        }
    };
    let (pol, pol_origin) = match (pol, &s.policy) {
        (Some(p), _) => (
            Some(p.to_string()),
            s.inputs
                .first()
                .map(|i| i.origin.clone())
                .unwrap_or(s.origin.clone()),
        ),
        (None, Some((p, o))) => (Some(p.clone()), o.clone()),
        (None, None) => (None, s.origin.clone()),
    };
    let policy = match pol {
        None if producer_live => Policy::DropOldest,
        None => Policy::Block,
        Some(p) => Policy::parse(&p).ok_or_else(|| {
            cerr(
                file,
                &pol_origin,
                &s.id,
                Some("policy"),
                format!("`{p}` is not a policy; use \"block\" or \"drop_oldest\""),
            )
        })?,
    };
    Ok((capacity, policy))
}

/// Kahn's algorithm, stable in declaration order; `Err(i)` names a stage on a cycle.
fn topo_order(preds: &[Vec<usize>]) -> Result<Vec<usize>, usize> {
    let n = preds.len();
    let mut indeg: Vec<usize> = preds.iter().map(Vec::len).collect();
    let mut succ = vec![Vec::new(); n];
    for (i, p) in preds.iter().enumerate() {
        for &j in p {
            succ[j].push(i);
        }
    }
    let mut done = vec![false; n];
    let mut order = Vec::with_capacity(n);
    while order.len() < n {
        let Some(i) = (0..n).find(|&i| !done[i] && indeg[i] == 0) else {
            return Err((0..n).find(|&i| !done[i]).unwrap_or(0));
        };
        done[i] = true;
        order.push(i);
        for &k in &succ[i] {
            indeg[k] -= 1;
        }
    }
    Ok(order)
}
