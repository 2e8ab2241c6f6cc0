//! URDF loading: revolute, continuous, prismatic, fixed and mimic joints.
//!
//! Links rigidly attached to the root are the base and carry no parameters. A link without
//! `<inertial>` that hangs on a fixed joint is a frame (a tool point, a sensor mount) and is folded
//! into its parent; every link moved by a joint must have a valid `<inertial>`.

use std::collections::HashMap;
use std::path::Path;

use crate::model::{ActuatedJoint, Body, CoulombLaws, Coupling, Frame, JointKind, Model, ModelWarning};
use crate::spatial::{params_from_com, rpy_to_rotation, Mat3, Vec3};

/// Why a URDF could not become a [`Model`]. Every variant names the offending element.
#[derive(Debug, thiserror::Error)]
pub enum UrdfError {
    #[error("cannot read URDF {path}: {source}")]
    Io { path: String, source: std::io::Error },
    #[error("URDF is not well-formed XML: {0}")]
    Xml(#[from] roxmltree::Error),
    #[error("the root element is <{0}>, expected <robot>")]
    NotARobot(String),
    #[error("link `{link}`: {what}")]
    Link { link: String, what: String },
    #[error("joint `{joint}`: {what}")]
    Joint { joint: String, what: String },
    #[error("the links form a cycle through `{0}`; a URDF must be a tree (cut closed loops with mimic joints)")]
    Cycle(String),
    #[error("the URDF has {0} root links ({1}); it must have exactly one")]
    Roots(usize, String),
    #[error("joint `{joint}` mimics `{target}`, which is not a joint of this robot")]
    MimicUnknown { joint: String, target: String },
    #[error(
        "joint `{joint}` mimics `{target}`, which is itself passive (a mimic or fixed joint); mimic an actuated joint"
    )]
    MimicPassive { joint: String, target: String },
    #[error("the robot has no actuated joint")]
    NoActuatedJoint,
}

struct Inertial {
    mass: f64,
    com: Vec3,
    rot: Mat3,
    tensor: Mat3,
}

struct RawJoint {
    name: String,
    kind: JointKind,
    continuous: bool,
    parent: String,
    child: String,
    origin_rot: Mat3,
    origin_pos: Vec3,
    axis: Vec3,
    limit: Option<(f64, f64, f64, f64)>,
    dynamics: (f64, f64),
    mimic: Option<(String, f64, f64)>,
}

/// Read and parse a URDF file.
pub fn load_urdf(path: impl AsRef<Path>) -> Result<Model, UrdfError> {
    let path = path.as_ref();
    let text =
        std::fs::read_to_string(path).map_err(|source| UrdfError::Io { path: path.display().to_string(), source })?;
    parse_urdf(&text)
}

/// Parse URDF text into a [`Model`] with gravity `(0, 0, −9.81)` m/s² in the root frame.
pub fn parse_urdf(text: &str) -> Result<Model, UrdfError> {
    let doc = roxmltree::Document::parse(text)?;
    let robot = doc.root_element();
    if robot.tag_name().name() != "robot" {
        return Err(UrdfError::NotARobot(robot.tag_name().name().to_string()));
    }
    let mut links: Vec<(String, Option<Inertial>)> = Vec::new();
    let mut joints: Vec<RawJoint> = Vec::new();
    for node in robot.children().filter(|n| n.is_element()) {
        match node.tag_name().name() {
            "link" => {
                let name = required_attr(node, "name", "link", "")?;
                let inertial = node
                    .children()
                    .find(|c| c.has_tag_name("inertial"))
                    .map(|i| parse_inertial(i, &name))
                    .transpose()?;
                links.push((name, inertial));
            }
            "joint" => joints.push(parse_joint(node)?),
            _ => {}
        }
    }
    TreeBuilder::new(robot.attribute("name").unwrap_or("robot"), links, joints)?.build()
}

fn required_attr(node: roxmltree::Node, attr: &str, element: &str, owner: &str) -> Result<String, UrdfError> {
    node.attribute(attr).map(str::to_string).ok_or_else(|| {
        let what = format!("<{element}> has no `{attr}` attribute");
        if element == "link" || owner.is_empty() {
            UrdfError::Link { link: owner.to_string(), what }
        } else {
            UrdfError::Joint { joint: owner.to_string(), what }
        }
    })
}

fn parse_numbers<const N: usize>(text: Option<&str>, default: [f64; N]) -> Result<[f64; N], String> {
    let Some(text) = text else { return Ok(default) };
    let values: Vec<f64> = text
        .split_whitespace()
        .map(|s| s.parse::<f64>().map_err(|_| format!("`{s}` is not a number")))
        .collect::<Result<_, _>>()?;
    let array: [f64; N] =
        values.try_into().map_err(|v: Vec<f64>| format!("expected {N} numbers, found {} in `{text}`", v.len()))?;
    if let Some(bad) = array.iter().find(|x| !x.is_finite()) {
        return Err(format!("`{bad}` is not finite in `{text}`"));
    }
    Ok(array)
}

fn number_attr(node: roxmltree::Node, attr: &str, default: Option<f64>) -> Result<f64, String> {
    match node.attribute(attr) {
        Some(s) => {
            let v: f64 =
                s.trim().parse().map_err(|_| format!("<{}> {attr}=`{s}` is not a number", node.tag_name().name()))?;
            if v.is_nan() {
                return Err(format!("<{}> {attr} is NaN", node.tag_name().name()));
            }
            Ok(v)
        }
        None => default.ok_or_else(|| format!("<{}> has no `{attr}` attribute", node.tag_name().name())),
    }
}

fn parse_origin(node: Option<roxmltree::Node>) -> Result<(Mat3, Vec3), String> {
    let Some(node) = node else {
        return Ok((Mat3::identity(), Vec3::zeros()));
    };
    let xyz = parse_numbers::<3>(node.attribute("xyz"), [0.0; 3]).map_err(|e| format!("<origin xyz>: {e}"))?;
    let rpy = parse_numbers::<3>(node.attribute("rpy"), [0.0; 3]).map_err(|e| format!("<origin rpy>: {e}"))?;
    Ok((rpy_to_rotation(rpy[0], rpy[1], rpy[2]), Vec3::from(xyz)))
}

fn parse_inertial(node: roxmltree::Node, link: &str) -> Result<Inertial, UrdfError> {
    let err = |what: String| UrdfError::Link { link: link.to_string(), what };
    let (rot, com) = parse_origin(node.children().find(|c| c.has_tag_name("origin"))).map_err(err)?;
    let mass_node =
        node.children().find(|c| c.has_tag_name("mass")).ok_or_else(|| err("<inertial> has no <mass>".into()))?;
    let mass = number_attr(mass_node, "value", None).map_err(err)?;
    let inertia =
        node.children().find(|c| c.has_tag_name("inertia")).ok_or_else(|| err("<inertial> has no <inertia>".into()))?;
    let mut e = [0.0; 6];
    for (slot, key) in e.iter_mut().zip(["ixx", "iyy", "izz", "ixy", "ixz", "iyz"]) {
        *slot = number_attr(inertia, key, Some(0.0)).map_err(err)?;
    }
    let tensor = Mat3::new(e[0], e[3], e[4], e[3], e[1], e[5], e[4], e[5], e[2]);
    Ok(Inertial { mass, com, rot, tensor })
}

fn parse_joint(node: roxmltree::Node) -> Result<RawJoint, UrdfError> {
    let name = node.attribute("name").ok_or_else(|| UrdfError::Joint {
        joint: String::from("<unnamed>"),
        what: "<joint> has no `name` attribute".into(),
    })?;
    let err = |what: String| UrdfError::Joint { joint: name.to_string(), what };
    let kind_text = required_attr(node, "type", "joint", name)?;
    let (kind, continuous) = match kind_text.as_str() {
        "revolute" => (JointKind::Revolute, false),
        "continuous" => (JointKind::Revolute, true),
        "prismatic" => (JointKind::Prismatic, false),
        "fixed" => (JointKind::Fixed, false),
        other => {
            return Err(err(format!("type `{other}` is not supported (revolute, continuous, prismatic or fixed)")))
        }
    };
    let link_of = |tag: &str| -> Result<String, UrdfError> {
        let n = node.children().find(|c| c.has_tag_name(tag)).ok_or_else(|| err(format!("has no <{tag}>")))?;
        required_attr(n, "link", tag, name)
    };
    let (parent, child) = (link_of("parent")?, link_of("child")?);
    let (origin_rot, origin_pos) = parse_origin(node.children().find(|c| c.has_tag_name("origin"))).map_err(err)?;
    let axis_node = node.children().find(|c| c.has_tag_name("axis"));
    let axis = Vec3::from(
        parse_numbers::<3>(axis_node.and_then(|a| a.attribute("xyz")), [1.0, 0.0, 0.0])
            .map_err(|e| err(format!("<axis>: {e}")))?,
    );
    if kind != JointKind::Fixed && axis.norm() < 1e-12 {
        return Err(err("<axis> is zero".into()));
    }
    let limit = match node.children().find(|c| c.has_tag_name("limit")) {
        Some(l) => Some((
            number_attr(l, "lower", Some(0.0)).map_err(err)?,
            number_attr(l, "upper", Some(0.0)).map_err(err)?,
            number_attr(l, "velocity", Some(0.0)).map_err(err)?,
            number_attr(l, "effort", Some(0.0)).map_err(err)?,
        )),
        None => None,
    };
    let dynamics = match node.children().find(|c| c.has_tag_name("dynamics")) {
        Some(d) => {
            (number_attr(d, "damping", Some(0.0)).map_err(err)?, number_attr(d, "friction", Some(0.0)).map_err(err)?)
        }
        None => (0.0, 0.0),
    };
    let mimic = match node.children().find(|c| c.has_tag_name("mimic")) {
        Some(m) => Some((
            required_attr(m, "joint", "mimic", name)?,
            number_attr(m, "multiplier", Some(1.0)).map_err(err)?,
            number_attr(m, "offset", Some(0.0)).map_err(err)?,
        )),
        None => None,
    };
    Ok(RawJoint {
        name: name.to_string(),
        kind,
        continuous,
        parent,
        child,
        origin_rot,
        origin_pos,
        axis: axis.normalize(),
        limit,
        dynamics,
        mimic,
    })
}

/// Where a link sits: on a moving body (or the base when `None`) at a fixed placement.
#[derive(Clone, Copy)]
struct Attachment {
    body: Option<usize>,
    rot: Mat3,
    pos: Vec3,
}

struct TreeBuilder {
    name: String,
    links: HashMap<String, Option<Inertial>>,
    joints: Vec<RawJoint>,
    children: HashMap<String, Vec<usize>>,
    root: String,
}

impl TreeBuilder {
    fn new(name: &str, links: Vec<(String, Option<Inertial>)>, joints: Vec<RawJoint>) -> Result<Self, UrdfError> {
        let mut link_map = HashMap::new();
        let mut order = Vec::new();
        for (link, inertial) in links {
            if link_map.contains_key(&link) {
                return Err(UrdfError::Link { link, what: "is defined twice".into() });
            }
            order.push(link.clone());
            link_map.insert(link, inertial);
        }
        let mut children: HashMap<String, Vec<usize>> = HashMap::new();
        let mut parent_of: HashMap<&str, &str> = HashMap::new();
        for (j, joint) in joints.iter().enumerate() {
            for link in [&joint.parent, &joint.child] {
                if !link_map.contains_key(link) {
                    return Err(UrdfError::Joint {
                        joint: joint.name.clone(),
                        what: format!("refers to unknown link `{link}`"),
                    });
                }
            }
            if let Some(previous) = parent_of.insert(&joint.child, &joint.parent) {
                return Err(UrdfError::Link {
                    link: joint.child.clone(),
                    what: format!(
                        "has two parents (`{previous}` and `{}`); cut closed loops with mimic joints",
                        joint.parent
                    ),
                });
            }
            children.entry(joint.parent.clone()).or_default().push(j);
        }
        if let Some(j) = joints.iter().find(|j| j.parent == j.child) {
            return Err(UrdfError::Cycle(j.child.clone()));
        }
        let roots: Vec<&String> = order.iter().filter(|l| !parent_of.contains_key(l.as_str())).collect();
        if roots.is_empty() {
            return Err(UrdfError::Cycle(order.first().cloned().unwrap_or_default()));
        }
        if roots.len() > 1 {
            let list = roots.iter().map(|s| s.as_str()).collect::<Vec<_>>().join(", ");
            return Err(UrdfError::Roots(roots.len(), list));
        }
        // Every link has at most one parent and there is one root, so a link unreachable from the
        // root can only be on a cycle.
        let root = roots[0].clone();
        let mut seen = std::collections::HashSet::from([root.as_str()]);
        let mut stack = vec![root.as_str()];
        while let Some(link) = stack.pop() {
            for &j in children.get(link).map(Vec::as_slice).unwrap_or(&[]) {
                if seen.insert(joints[j].child.as_str()) {
                    stack.push(joints[j].child.as_str());
                }
            }
        }
        if let Some(lost) = order.iter().find(|l| !seen.contains(l.as_str())) {
            return Err(UrdfError::Cycle(lost.clone()));
        }
        Ok(Self { name: name.to_string(), links: link_map, joints, children, root })
    }

    fn build(self) -> Result<Model, UrdfError> {
        let mut bodies: Vec<Body> = Vec::new();
        let mut mimics: Vec<(usize, String, f64, f64)> = Vec::new();
        let mut actuated: Vec<ActuatedJoint> = Vec::new();
        let mut warnings: Vec<ModelWarning> = Vec::new();
        let identity = Attachment { body: None, rot: Mat3::identity(), pos: Vec3::zeros() };
        let mut frames = vec![Frame { name: self.root.clone(), body: None, rot: identity.rot, pos: identity.pos }];
        // Depth first, children in document order, so bodies are numbered parents first, as
        // Pinocchio numbers its joints.
        let mut stack: Vec<(usize, Attachment)> = Vec::new();
        self.push_children(&self.root, identity, &mut stack);
        while let Some((j, at)) = stack.pop() {
            let joint = &self.joints[j];
            let placed =
                Attachment { body: at.body, rot: at.rot * joint.origin_rot, pos: at.pos + at.rot * joint.origin_pos };
            let (child_at, warning) = self.attach(joint, placed, &mut bodies, &mut mimics, &mut actuated)?;
            warnings.extend(warning);
            if child_at.body == placed.body && joint.kind == JointKind::Fixed {
                frames.push(Frame { name: joint.child.clone(), body: placed.body, rot: placed.rot, pos: placed.pos });
            }
            self.push_children(&joint.child, child_at, &mut stack);
        }
        if actuated.is_empty() {
            return Err(UrdfError::NoActuatedJoint);
        }
        for (b, target, multiplier, offset) in mimics {
            let Some(index) = actuated.iter().position(|a| a.name == target) else {
                let exists = self.joints.iter().any(|j| j.name == target);
                let joint = bodies[b].joint.clone();
                return Err(if exists {
                    UrdfError::MimicPassive { joint, target }
                } else {
                    UrdfError::MimicUnknown { joint, target }
                });
            };
            bodies[b].coupling = Some(Coupling { index, multiplier, offset });
        }
        Ok(Model {
            name: self.name,
            bodies,
            coulomb_laws: CoulombLaws::undeclared(actuated.len()),
            joints: actuated,
            gravity: Vec3::new(0.0, 0.0, -9.81),
            warnings,
            frames,
        })
    }

    fn push_children(&self, link: &str, at: Attachment, stack: &mut Vec<(usize, Attachment)>) {
        for &j in self.children.get(link).map(Vec::as_slice).unwrap_or(&[]).iter().rev() {
            stack.push((j, at));
        }
    }

    /// Create the body (if any) that `joint` brings in, and say where its child link sits and
    /// what about the link deserves a warning.
    fn attach(
        &self,
        joint: &RawJoint,
        at: Attachment,
        bodies: &mut Vec<Body>,
        mimics: &mut Vec<(usize, String, f64, f64)>,
        actuated: &mut Vec<ActuatedJoint>,
    ) -> Result<(Attachment, Option<ModelWarning>), UrdfError> {
        let inertial = self.links[&joint.child].as_ref();
        let link_err = |what: String| UrdfError::Link { link: joint.child.clone(), what };
        if joint.kind == JointKind::Fixed {
            if joint.mimic.is_some() {
                return Err(UrdfError::Joint { joint: joint.name.clone(), what: "a fixed joint cannot mimic".into() });
            }
            let is_frame = at.body.is_none() || inertial.is_none_or(|i| i.mass == 0.0 && i.tensor.norm() == 0.0);
            if is_frame {
                return Ok((at, None));
            }
        }
        let inertial =
            inertial.ok_or_else(|| link_err(format!("is moved by joint `{}` but has no <inertial>", joint.name)))?;
        let (params, semidefinite) = validated_params(inertial).map_err(link_err)?;
        let warning = semidefinite
            .map(|eigenvalues| ModelWarning::SemidefiniteInertia { link: joint.child.clone(), eigenvalues });
        let index = bodies.len();
        let coupling = match (&joint.mimic, joint.kind) {
            (_, JointKind::Fixed) => None,
            (Some((target, multiplier, offset)), _) => {
                mimics.push((index, target.clone(), *multiplier, *offset));
                None
            }
            (None, kind) => {
                actuated.push(actuated_joint(joint, kind, index));
                Some(Coupling { index: actuated.len() - 1, multiplier: 1.0, offset: 0.0 })
            }
        };
        bodies.push(Body {
            name: joint.child.clone(),
            joint: joint.name.clone(),
            parent: at.body,
            kind: joint.kind,
            axis: joint.axis,
            origin_rot: at.rot,
            origin_pos: at.pos,
            coupling,
            inertial: params,
        });
        Ok((Attachment { body: Some(index), rot: Mat3::identity(), pos: Vec3::zeros() }, warning))
    }
}

fn actuated_joint(joint: &RawJoint, kind: JointKind, body: usize) -> ActuatedJoint {
    let (lower, upper, velocity, effort) = match (joint.continuous, joint.limit) {
        (false, Some((lo, hi, v, e))) => (lo, hi, v, e),
        (true, Some((_, _, v, e))) => (f64::NEG_INFINITY, f64::INFINITY, v, e),
        (_, None) => (f64::NEG_INFINITY, f64::INFINITY, 0.0, 0.0),
    };
    let positive_or_inf = |x: f64| if x > 0.0 { x } else { f64::INFINITY };
    ActuatedJoint {
        name: joint.name.clone(),
        body,
        kind,
        lower,
        upper,
        velocity: positive_or_inf(velocity),
        effort: positive_or_inf(effort),
        viscous: joint.dynamics.0,
        coulomb: joint.dynamics.1,
    }
}

/// A link's ten parameters, and its principal moments when the inertia is only positive
/// semidefinite (a point mass, a thin rod). Generated URDFs often give a small link no rotational
/// inertia, and Pinocchio loads it; a tensor no body can have (negative, or principal moments
/// that break the triangle inequality) is refused.
fn validated_params(inertial: &Inertial) -> Result<([f64; 10], Option<[f64; 3]>), String> {
    if inertial.mass.is_nan() || inertial.mass <= 0.0 {
        return Err(format!("mass {} kg is not positive", inertial.mass));
    }
    let mut eig: Vec<f64> = inertial.tensor.symmetric_eigenvalues().iter().copied().collect();
    eig.sort_by(f64::total_cmp);
    let (named, largest) = ([eig[0], eig[1], eig[2]], eig[2].abs());
    // Round-off of a tensor typed with a few digits, relative to its size.
    let tolerance = 1e-9 * largest;
    if eig.iter().any(|e| e.is_nan()) || eig[0] < -tolerance {
        return Err(format!(
            "inertia tensor is not positive definite, not even semidefinite (eigenvalues {:.3e}, {:.3e}, {:.3e} kg·m²)",
            named[0], named[1], named[2]
        ));
    }
    if eig[0] + eig[1] < eig[2] - tolerance {
        return Err(format!(
            "principal moments {:.3e}, {:.3e}, {:.3e} kg·m² break the triangle inequality (the two smaller must add up to the largest): no body has them",
            named[0], named[1], named[2]
        ));
    }
    let tensor = inertial.rot * inertial.tensor * inertial.rot.transpose();
    let semidefinite = (eig[0] <= tolerance).then_some(named);
    Ok((params_from_com(inertial.mass, &inertial.com, &tensor), semidefinite))
}

#[cfg(test)]
mod tests {
    use super::*;

    const LINK: &str = r#"<inertial><mass value="1"/><inertia ixx="0.1" iyy="0.1" izz="0.1"/></inertial>"#;

    fn robot(links: &[(&str, &str)], joints: &str) -> String {
        let links: String =
            links.iter().map(|(name, inner)| format!(r#"<link name="{name}">{inner}</link>"#)).collect();
        format!(r#"<robot name="t">{links}{joints}</robot>"#)
    }

    fn joint(name: &str, kind: &str, parent: &str, child: &str, extra: &str) -> String {
        format!(
            r#"<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" velocity="1" effort="1"/>{extra}</joint>"#
        )
    }

    fn error_of(text: &str) -> String {
        parse_urdf(text).expect_err("the URDF should be refused").to_string()
    }

    #[test]
    fn accepts_a_valid_arm_with_a_mimic_joint() {
        let j = joint("a", "revolute", "base", "l1", "")
            + &joint("b", "revolute", "l1", "l2", r#"<mimic joint="a" multiplier="2" offset="0.1"/>"#);
        let model = parse_urdf(&robot(&[("base", ""), ("l1", LINK), ("l2", LINK)], &j)).unwrap();
        assert_eq!((model.dof(), model.bodies.len(), model.num_params()), (1, 2, 23));
        let c = model.bodies[1].coupling.unwrap();
        assert_eq!((c.index, c.multiplier, c.offset), (0, 2.0, 0.1));
    }

    /// An inner body reaches its children's joints (a sliding one over its travel) or twice its
    /// own centre of mass, whichever is farther; the last body of the chain, where tools go,
    /// the whole robot's reach. Figures worked by hand from the text below.
    #[test]
    fn a_body_extends_to_its_childrens_joints_and_the_last_to_the_whole_reach() {
        let com = |x: f64| {
            format!(
                r#"<inertial><origin xyz="{x} 0 0"/><mass value="1"/><inertia ixx="0.1" iyy="0.1" izz="0.1"/></inertial>"#
            )
        };
        let (l1, l2, tip) = (com(0.1), com(0.05), com(0.02));
        let j = joint("a", "revolute", "base", "l1", r#"<origin xyz="0 0 0.5"/>"#)
            + &joint("b", "revolute", "l1", "l2", r#"<origin xyz="0.3 0 0.4"/>"#)
            + &joint("c", "prismatic", "l2", "tip", r#"<origin xyz="0 0 0.06"/>"#);
        let model = parse_urdf(&robot(&[("base", ""), ("l1", &l1), ("l2", &l2), ("tip", &tip)], &j)).unwrap();
        let extent = |name: &str| model.body_extent_m(model.bodies.iter().position(|b| b.name == name).unwrap());
        // l1: its child's joint 0.5 m away, beyond twice its centre of mass (0.2 m).
        assert!((extent("l1") - 0.5).abs() < 1e-12, "{}", extent("l1"));
        // l2: its child slides 2 m (limits ±1) from 0.06 m.
        assert!((extent("l2") - 2.06).abs() < 1e-12, "{}", extent("l2"));
        // The tip: 0.5 + 0.5 + 0.06 + 2 of joints and travel, and twice the farthest centre of mass.
        assert!((extent("tip") - (3.06 + 0.2)).abs() < 1e-12, "{}", extent("tip"));
    }

    #[test]
    fn missing_inertial_names_the_link() {
        let e = error_of(&robot(&[("base", ""), ("l1", "")], &joint("a", "revolute", "base", "l1", "")));
        assert!(e.contains("`l1`") && e.contains("no <inertial>"), "{e}");
    }

    #[test]
    fn mimic_of_an_unknown_joint_is_refused() {
        let j =
            joint("a", "revolute", "base", "l1", "") + &joint("b", "revolute", "l1", "l2", r#"<mimic joint="ghost"/>"#);
        let e = error_of(&robot(&[("base", ""), ("l1", LINK), ("l2", LINK)], &j));
        assert!(e.contains("`b`") && e.contains("`ghost`") && e.contains("not a joint"), "{e}");
    }

    #[test]
    fn mimic_of_a_passive_joint_is_refused() {
        let j = joint("a", "revolute", "base", "l1", "")
            + &joint("b", "revolute", "l1", "l2", r#"<mimic joint="a"/>"#)
            + &joint("c", "revolute", "l2", "l3", r#"<mimic joint="b"/>"#);
        let e = error_of(&robot(&[("base", ""), ("l1", LINK), ("l2", LINK), ("l3", LINK)], &j));
        assert!(e.contains("`c`") && e.contains("`b`") && e.contains("passive"), "{e}");
    }

    #[test]
    fn a_cycle_is_refused() {
        // l1 → l2 → l1, with base as a separate root: every link has one parent.
        let j = joint("a", "revolute", "l1", "l2", "") + &joint("b", "revolute", "l2", "l1", "");
        let e = error_of(&robot(&[("base", ""), ("l1", LINK), ("l2", LINK)], &j));
        assert!(e.contains("cycle"), "{e}");
        let e = error_of(&robot(&[("l1", LINK)], &joint("a", "revolute", "l1", "l1", "")));
        assert!(e.contains("cycle") && e.contains("`l1`"), "{e}");
    }

    #[test]
    fn a_closed_loop_without_mimic_is_refused() {
        let j = joint("a", "revolute", "base", "l1", "")
            + &joint("b", "revolute", "base", "l2", "")
            + &joint("c", "revolute", "l1", "l2", "");
        let e = error_of(&robot(&[("base", ""), ("l1", LINK), ("l2", LINK)], &j));
        assert!(e.contains("`l2`") && e.contains("two parents"), "{e}");
    }

    #[test]
    fn non_positive_mass_is_refused() {
        for mass in ["0", "-1"] {
            let inner =
                format!(r#"<inertial><mass value="{mass}"/><inertia ixx="0.1" iyy="0.1" izz="0.1"/></inertial>"#);
            let e = error_of(&robot(&[("base", ""), ("l1", &inner)], &joint("a", "revolute", "base", "l1", "")));
            assert!(e.contains("`l1`") && e.contains("not positive"), "{e}");
        }
    }

    #[test]
    fn a_point_mass_or_a_rod_loads_with_a_warning_that_names_the_link() {
        for (inertia, zeros) in [(r#"ixx="0" iyy="0" izz="0""#, 3), (r#"ixx="0.1" iyy="0.1" izz="0""#, 1)] {
            let inner = format!(r#"<inertial><mass value="0.2"/><inertia {inertia}/></inertial>"#);
            let text = robot(
                &[("base", ""), ("l1", LINK), ("tip", &inner)],
                &(joint("a", "revolute", "base", "l1", "") + &joint("b", "revolute", "l1", "tip", "")),
            );
            let model = parse_urdf(&text).unwrap();
            assert_eq!(model.warnings.len(), 1, "{:?}", model.warnings);
            let ModelWarning::SemidefiniteInertia { link, eigenvalues } = &model.warnings[0];
            assert_eq!(link, "tip");
            assert_eq!(eigenvalues.iter().filter(|e| **e == 0.0).count(), zeros);
            assert!(model.warnings[0].to_string().contains("link `tip`"));
            assert_eq!(model.bodies[1].inertial[0], 0.2);
        }
        let clean =
            parse_urdf(&robot(&[("base", ""), ("l1", LINK)], &joint("a", "revolute", "base", "l1", ""))).unwrap();
        assert!(clean.warnings.is_empty());
    }

    #[test]
    fn principal_moments_that_break_the_triangle_inequality_are_refused() {
        let inner = r#"<inertial><mass value="1"/><inertia ixx="0.1" iyy="0.1" izz="0.3"/></inertial>"#;
        let e = error_of(&robot(&[("base", ""), ("l1", inner)], &joint("a", "revolute", "base", "l1", "")));
        assert!(e.contains("`l1`") && e.contains("triangle inequality"), "{e}");
    }

    #[test]
    fn an_inertia_that_is_not_positive_definite_is_refused() {
        let inner = r#"<inertial><mass value="1"/><inertia ixx="0.1" ixy="0.2" iyy="0.1" izz="0.1"/></inertial>"#;
        let e = error_of(&robot(&[("base", ""), ("l1", inner)], &joint("a", "revolute", "base", "l1", "")));
        assert!(e.contains("`l1`") && e.contains("not positive definite"), "{e}");
    }

    #[test]
    fn malformed_input_is_refused_with_its_location() {
        assert!(error_of("<robot><link").contains("not well-formed"));
        assert!(error_of("<model/>").contains("<model>"));
        let e = error_of(&robot(&[("base", ""), ("l1", LINK)], &joint("a", "revolute", "base", "nowhere", "")));
        assert!(e.contains("`a`") && e.contains("`nowhere`"), "{e}");
        let e = error_of(&robot(&[("base", ""), ("l1", LINK)], &joint("a", "screw", "base", "l1", "")));
        assert!(e.contains("`screw`"), "{e}");
        let bad_origin = r#"<origin xyz="0 zero 0"/>"#;
        let e = error_of(&robot(&[("base", ""), ("l1", LINK)], &joint("a", "revolute", "base", "l1", bad_origin)));
        assert!(e.contains("`a`") && e.contains("`zero`"), "{e}");
        let e =
            error_of(&robot(&[("base", ""), ("l1", LINK), ("l2", LINK)], &joint("a", "revolute", "base", "l1", "")));
        assert!(e.contains("2 root links") && e.contains("l2"), "{e}");
    }

    #[test]
    fn massless_fixed_frames_fold_into_their_parent() {
        let tip = r#"<origin xyz="0 0 0.1" rpy="0 0 0"/>"#;
        let j = joint("a", "prismatic", "base", "l1", "") + &joint("tip", "fixed", "l1", "tcp", tip);
        let model = parse_urdf(&robot(&[("base", ""), ("l1", LINK), ("tcp", "")], &j)).unwrap();
        assert_eq!(model.bodies.len(), 1);
        let tcp = model.frame("tcp").unwrap();
        assert_eq!(tcp.body, Some(0), "the tool point moves with l1");
        assert_eq!(tcp.pos, Vec3::new(0.0, 0.0, 0.1));
        assert_eq!(model.frame("l1").unwrap().body, Some(0));
        assert_eq!(model.frame("base").unwrap().body, None);
        let e = model.frame("flange").unwrap_err().to_string();
        assert!(e.contains("`flange`") && e.contains("l1, base, tcp"), "{e}");
    }
}
