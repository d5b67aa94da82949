//! The final model of a diagnosis as a `model.json` ([`ModelFile`], kind `structure`), so
//! that `optbench simulate --model` runs it on any input.

use super::refit::Fitted;
use crate::physics::model_file::{
    Integration, ModelFile, Named, Normalisation, Param, RecordState, StructureContext,
    StructureSpec, Units,
};
use crate::physics::structure::CoreKind;

/// The validation record's own state, where it is one record at one interval.
pub struct ValidationState {
    pub name: String,
    pub dt: f64,
    pub theta: Vec<f64>,
    pub coef: Vec<f64>,
}

/// The unit of one of [`crate::physics::structure::Structure::named_params`] from its name:
/// input `ui`, output `uo`.
fn unit(name: &str, ui: &str, uo: &str, ratio: &str) -> String {
    let per = |a: &str, b: &str| {
        if a.is_empty() && b.is_empty() {
            String::new()
        } else {
            format!("{a}/{b}")
        }
    };
    match name {
        "d_e" | "alpha" => ratio.into(),
        "beta" | "gamma" if !ratio.is_empty() => format!("{uo}^(1-n)/{ui}"),
        "d0" | "h0" | "z0" => uo.into(),
        n if n.starts_with('w') && n[1..].parse::<usize>().is_ok() => ratio.into(),
        n if n.starts_with('r') && n[1..].parse::<usize>().is_ok() => ui.into(),
        "mass" => per(&format!("{ui} s^2"), uo),
        "damping" => per(&format!("{ui} s"), uo),
        "stiffness" => per(ui, uo),
        "saturation_limit_input" | "saturation_scale_input" => ui.into(),
        "asymmetry_q_per_input" => per("1", ui),
        "drift_per_s" => per(uo, "s"),
        "drift_per_s2" => per(uo, "s^2"),
        n if n.ends_with("_hz") => "Hz".into(),
        n if n.ends_with("_s") => "s".into(),
        _ => String::new(),
    }
}

fn named(names: Vec<String>, values: &[f64]) -> Vec<Named> {
    names
        .into_iter()
        .zip(values)
        .map(|(name, &value)| Named { name, value })
        .collect()
}

/// `f` (the first record's model of a joint fit) as a model file: the physical parameters
/// for the reader, the structure with its shape (search bounds flagged, except where a
/// bound is the parameter's neutral value: an effect or nuisance at rest is not stuck) and
/// linear coefficients to run it, and the validation record's own state if given.
pub fn model_file(f: &Fitted, units: [&str; 3], validation: Option<ValidationState>) -> ModelFile {
    let f = f.single();
    let st = &f.structure;
    let ctx = st.context();
    let [ut, ui, uo] = units;
    let ratio = if ui.is_empty() && uo.is_empty() {
        String::new()
    } else {
        format!("{uo}/{ui}")
    };
    let parameters = st
        .named_params(&f.theta, &f.linear.coef)
        .into_iter()
        .map(|(name, value)| {
            let u = unit(&name, ui, uo, &ratio);
            Param::new(name, value, u)
        })
        .collect();
    let shape = st
        .specs()
        .iter()
        .zip(&f.theta)
        .map(|(s, &x)| {
            let mut p = Param::new(s.name, x, "").searched(x, s.lower, s.upper);
            if let Some(search) = &mut p.search {
                let bound = match search.at_bound.as_deref() {
                    Some("lower") => s.lower,
                    _ => s.upper,
                };
                if bound == s.neutral {
                    search.at_bound = None;
                }
            }
            p
        })
        .collect();
    let structure = StructureSpec {
        effects: st
            .parts()
            .into_iter()
            .map(|(e, form)| [e.name().to_string(), form.name().to_string()])
            .collect(),
        fixed_n: st.fixed_n(),
        placement: st.placement().name().into(),
        context: StructureContext {
            dt: ctx.dt,
            u_ref: ctx.u_ref,
            rate_ref: ctx.rate_ref,
            t_ref: ctx.t_ref,
            hold: ctx.hold.name().into(),
            min_substeps: ctx.min_substeps,
            pi: ctx.pi,
        },
        shape,
        linear: named(st.linear_names(), &f.linear.coef),
    };
    let mut m = ModelFile::new(
        "structure",
        &format!(
            "{}: {} with the extensions `optbench diagnose` accepted (physics::structure), shape unit-free on the training data's context, linear coefficients ({}) in the recording's units",
            st.label(),
            match ctx.pi.map(|p| p.kind) {
                Some(CoreKind::Plays) => "a Prandtl-Ishlinskii core (plays with fixed thresholds)",
                Some(CoreKind::Relays) => "a Preisach core (relays with fixed thresholds)",
                None => "Bouc-Wen",
            },
            match ctx.pi.map(|p| p.kind) {
                Some(CoreKind::Plays) => "play weights, offset, drift, creep states",
                Some(CoreKind::Relays) => "relay weights, offset, drift, creep states",
                None => "gain, offset, hysteretic scale, drift, creep states",
            }
        ),
        Units {
            time: ut.into(),
            input: ui.into(),
            output: uo.into(),
        },
        ctx.dt,
        Normalisation {
            input_scale: ctx.u_ref,
            output_scale: 1.0,
        },
        Integration {
            scheme: "structure".into(),
            substeps: None,
            hold: Some(ctx.hold.name().into()),
        },
        "the training record's fitted initial state, timing, offset, drift and creep states (structure.shape and .linear); with --record validate the validation record's own, refitted on it",
        parameters,
    );
    m.structure = Some(structure);
    if let Some(v) = validation {
        let vs = st.at_interval(v.dt);
        m.records.push(RecordState {
            label: "validate".into(),
            name: v.name,
            sampling_interval_s: v.dt,
            d0: None,
            h0: None,
            substeps: None,
            shape: named(
                vs.specs().iter().map(|s| s.name.to_string()).collect(),
                &v.theta,
            ),
            linear: named(vs.linear_names(), &v.coef),
        });
    }
    m
}
