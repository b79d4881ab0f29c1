//! The `ssd:DefaultExperiment` annotations the reader interprets: OSP step size, recorded signals.

use super::xml::{ssp_children, Doc, Node, Ns};
use super::{Error, OSP_ANNOTATION, RECORD_ANNOTATION};

/// The OSP `FixedStepAlgorithm baseStepSize` in `ssd:DefaultExperiment/ssd:Annotations`.
pub(super) fn read_step_size(d: &Doc, experiment: &Node) -> Result<Option<f64>, Error> {
    let mut step = None;
    for (ns, local, annotations) in ssp_children(experiment) {
        if (ns, local) != (Ns::Ssd, "Annotations") {
            return Err(d.unexpected(annotations, experiment));
        }
        for (ns, local, a) in ssp_children(annotations) {
            if (ns, local) != (Ns::Ssc, "Annotation") {
                return Err(d.unexpected(a, annotations));
            }
            if d.attr(a, "type")? != OSP_ANNOTATION {
                continue;
            }
            for algorithms in a.children.iter().filter(|c| c.local == "Algorithm") {
                for alg in &algorithms.children {
                    if alg.local != "FixedStepAlgorithm" {
                        return Err(
                            d.err(alg, "unsupported OSP algorithm (only FixedStepAlgorithm)")
                        );
                    }
                    let h = d
                        .real_attr(alg, "baseStepSize")?
                        .ok_or_else(|| d.err(alg, "missing required attribute 'baseStepSize'"))?;
                    if !(h > 0.0 && h.is_finite()) {
                        return Err(d.err(alg, format_args!("baseStepSize {h} is not positive")));
                    }
                    step = Some(h);
                }
            }
        }
    }
    Ok(step)
}

/// The signals of the [`RECORD_ANNOTATION`] in `ssd:DefaultExperiment/ssd:Annotations` (after
/// [`read_step_size`] checked the annotations' shape).
pub(super) fn read_record(d: &Doc, experiment: &Node) -> Result<Vec<String>, Error> {
    let mut record = Vec::new();
    for (_, _, annotations) in ssp_children(experiment) {
        for (_, _, a) in ssp_children(annotations) {
            if d.attr(a, "type")? != RECORD_ANNOTATION {
                continue;
            }
            for r in &a.children {
                if r.local != "Record" {
                    return Err(d.err(r, "unexpected element (the record annotation holds <Record signals=\"...\"/>)"));
                }
                let signals = d.attr(r, "signals")?;
                record.extend(
                    signals
                        .split(',')
                        .map(str::trim)
                        .filter(|p| !p.is_empty())
                        .map(String::from),
                );
            }
        }
    }
    Ok(record)
}
