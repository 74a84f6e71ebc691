//! The mass properties of a URDF arm (its links' `<inertial>`), in the frames of the chain
//! [`urdf::parse`] imports, for [`kinematics::dynamics::Dynamics`]: each moving joint's link with
//! every link fixed to it (the tool frame's, a camera) combined into one body, and what hangs off
//! the chain through other joints (the SO-101's moving jaw) carried rigidly at those joints' zero.
//! Read from the file on demand, not kept in the arm file.

use crate::urdf::{self, child, UrdfKind};
use anyhow::{anyhow, bail, Result};
use kinematics::dynamics::Inertia;
use kinematics::nalgebra::{Matrix3, Vector3};
use kinematics::Pose;
use roxmltree::{Document, Node};
use std::collections::BTreeMap;

/// The arm's mass properties.
#[derive(Clone, Debug, PartialEq)]
pub struct Masses {
    /// What the base carries (the root link and every link fixed to it): moved by no joint.
    pub base: Inertia<f64>,
    /// One body per moving joint of the chain, in that joint's moving frame (base first).
    pub links: Vec<Inertia<f64>>,
    /// Links that have no `<inertial>`, taken as massless (URDF's default), by name.
    pub massless: Vec<String>,
    /// Links off the chain carried rigidly at their joints' zero, with the joint that would move
    /// them: "moving_jaw_so101_v1_link (joint gripper)".
    pub carried: Vec<String>,
}

/// The masses of the chain from the root link to `tip` (or the only leaf), as [`urdf::parse`]
/// chooses it. Fails in one line naming the link and the line of the file for an `<inertial>` that
/// cannot be read or is not a body's (a mass not finite or negative, a tensor that breaks the
/// triangle inequality), and when no link of the chain has mass.
pub fn masses(text: &str, tip: Option<&str>) -> Result<Masses> {
    // `parse` checks the tree, the joints and the tip, with its errors; the walk below relies on it.
    let spec = urdf::parse(text, tip)?;
    let doc = Document::parse(text)?;
    let (links, parent_joint) = urdf::links_and_joints(&doc)?;
    // The chain's moving joints, by name, and the frame each moves (1 for the first).
    let frames: BTreeMap<&str, usize> = spec.joints.iter().enumerate().map(|(k, j)| (j.name.as_str(), k + 1)).collect();

    let mut bodies = vec![Inertia::zero(); spec.dof() + 1];
    let (mut massless, mut carried) = (Vec::new(), Vec::new());
    for (&name, &node) in &links {
        // Up from the link to the first joint of the chain that moves it (or the root), composing
        // the fixed joints' origins, and other joints' at their zero, on the way.
        let (mut at, mut current, mut frame, mut off_chain) = (Pose::identity(), name, 0, None);
        while let Some(joint) = parent_joint.get(current) {
            if let Some(&k) = frames.get(joint.name) {
                frame = k;
                break;
            }
            if matches!(joint.kind, UrdfKind::Moving(_)) {
                off_chain.get_or_insert(joint.name);
            }
            at = joint.origin.compose(&at);
            current = joint.parent;
        }
        let Some(inertial) = child(node, "inertial") else {
            massless.push(name.to_string());
            continue;
        };
        let body = read_inertial(inertial, name)?;
        if let Some(joint) = off_chain {
            carried.push(format!("{name} (joint {joint})"));
        }
        bodies[frame] = bodies[frame].combined(&body.moved(&at.rotation, &at.translation));
    }
    let base = bodies.remove(0);
    if bodies.iter().all(|b| b.mass <= 0.0) {
        bail!("{}: no link the joints move has an <inertial> with mass: the URDF gives no dynamics", spec.name);
    }
    Ok(Masses { base, links: bodies, massless, carried })
}

/// One `<inertial>`: the centre of mass at its `<origin>`, the tensor in that origin's axes.
fn read_inertial(node: Node, link: &str) -> Result<Inertia<f64>> {
    let owner = format!("link {link} <inertial>");
    let line = urdf::line_of(node);
    let origin = urdf::origin(child(node, "origin"), &owner)?;
    let value = |element: &str, attribute: &str| -> Result<f64> {
        let e = child(node, element).ok_or_else(|| anyhow!("line {line}: {owner} has no <{element}>"))?;
        let text = e
            .attribute(attribute)
            .ok_or_else(|| anyhow!("line {}: {owner}: <{element}> has no {attribute}", urdf::line_of(e)))?;
        urdf::number(text, e, attribute, &owner, urdf::line_of(e))
    };
    let mass = value("mass", "value")?;
    let (xx, xy, xz) = (value("inertia", "ixx")?, value("inertia", "ixy")?, value("inertia", "ixz")?);
    let (yy, yz, zz) = (value("inertia", "iyy")?, value("inertia", "iyz")?, value("inertia", "izz")?);
    let tensor = Matrix3::new(xx, xy, xz, xy, yy, yz, xz, yz, zz);
    let body = Inertia { mass, com: Vector3::zeros(), tensor }
        .validated()
        .map_err(|e| anyhow!("line {line}: {owner}: {e}"))?;
    Ok(body.moved(&origin.rotation, &origin.translation))
}

#[cfg(test)]
mod tests {
    use super::*;

    const SO101: &str = include_str!("../../tests/data/so101_new_calib.urdf");
    /// The preset's tip: the tool frame's link (the jaw is the other leaf).
    const TIP: Option<&str> = Some("gripper_frame_link");

    /// The SO-101's links as its URDF gives them: each joint's link, the tool frame's link fixed
    /// to the wrist roll's, the moving jaw carried at the gripper's zero.
    #[test]
    fn the_so101s_masses_are_its_links_in_the_chains_frames() {
        let m = masses(SO101, TIP).unwrap();
        assert_eq!(m.links.len(), 5);
        assert!((m.base.mass - 0.147).abs() < 1e-12);
        let expected = [0.100006, 0.103, 0.104, 0.079, 0.087 + 1e-9 + 0.012];
        for (link, mass) in m.links.iter().zip(expected) {
            assert!((link.mass - mass).abs() < 1e-12, "{} against {mass}", link.mass);
        }
        assert_eq!(m.carried, vec!["moving_jaw_so101_v1_link (joint gripper)".to_string()]);
        assert!(m.massless.is_empty(), "{:?}", m.massless);
        // The wrist roll's body, by hand from the file's numbers: the gripper link's centre of
        // mass, and the jaw's carried through the gripper joint's origin (xyz, rpy) at zero.
        let gripper = Vector3::new(0.000213627, 0.000245138, -0.025187);
        // The file's roll, 1.5708, as written (not π/2).
        #[allow(clippy::approx_constant)]
        let roll = 1.5708;
        let jaw_origin = Pose::from_xyz_rpy([0.0202, 0.0188, -0.0234], [roll, -5.24284e-08, -1.41553e-15]);
        let jaw = jaw_origin.rotation * Vector3::new(-0.00157495, -0.0300244, 0.0192755) + jaw_origin.translation;
        let com = (gripper * 0.087 + jaw * 0.012) / (0.087 + 0.012 + 1e-9);
        assert!((m.links[4].com - com).norm() < 1e-6, "{} against {com}", m.links[4].com);
    }

    #[test]
    fn bad_inertials_are_refused_in_one_line_naming_the_link() {
        let nan = SO101.replacen(r#"<mass value="0.103"/>"#, r#"<mass value="nan"/>"#, 1);
        let e = masses(&nan, TIP).unwrap_err().to_string();
        assert!(e.contains("link upper_arm_link <inertial>") && e.contains("not a finite number"), "{e}");
        let negative = SO101.replacen(r#"<mass value="0.103"/>"#, r#"<mass value="-0.103"/>"#, 1);
        let e = masses(&negative, TIP).unwrap_err().to_string();
        assert!(e.contains("upper_arm_link") && e.contains("negative"), "{e}");
        let flat = SO101.replacen(r#"izz="0.000142487""#, r#"izz="0.001""#, 1);
        let e = masses(&flat, TIP).unwrap_err().to_string();
        assert!(e.contains("upper_arm_link") && e.contains("triangle"), "{e}");
        let none = without_inertials(SO101);
        let e = masses(&none, TIP).unwrap_err().to_string();
        assert!(e.contains("no dynamics") && !e.contains('\n'), "{e}");
    }

    // Recorded from Pinocchio: host/tests/data/so101_dynamics_values.py.
    // Pinocchio 4.1.0, host/tests/data/so101_dynamics_values.py
    /// Joint positions, velocities, accelerations, and the torques they take.
    type State = ([f64; 5], [f64; 5], [f64; 5], [f64; 5]);
    const PINOCCHIO_RNEA: [State; 8] = [
        (
            [0.006573436113404885, 0.1373065290287414, -1.230745197391125, -0.6420453727255682, 0.4909311821884086],
            [1.1651465579862461, -1.3957040692022318, -1.0833445332029354, 1.7614000259399467, 0.6646699834618017],
            [2.6463378787976595, 1.5929891064031496, -2.880136029806013, -2.6945765255100884, -2.7575341582333013],
            [
                -0.025604295088178967,
                -0.29148934182576136,
                -0.14288668668665408,
                0.008586841803418892,
                0.00024255531756495863,
            ],
        ),
        (
            [-0.06955664801584205, 0.2263331693632349, 1.6091719188933746, 0.9747592703634009, -2.0830620957320605],
            [1.4130456393445114, -0.8904311491203227, -0.9837999356774394, -0.3423046920066275, 1.1070342862400637],
            [3.0456074913143176, 2.7202172177929906, 0.11075918149784592, -3.266742945806919, -1.1742567818674319],
            [
                0.002148341504704811,
                0.014076037284299518,
                0.18587470643649145,
                0.1141259321772173,
                -0.0021291508180888083,
            ],
        ),
        (
            [0.4097316105528668, -0.4831284212621274, -0.880789334278165, 1.0339407817857713, -2.5834083644547334],
            [0.2277784203798361, 1.8780625414636014, -0.13959784726844227, 1.0370193758448405, -1.056053746714301],
            [4.041399120911986, 1.6167631045996975, 0.5712887500736095, -4.167917756829176, 2.3676192666275817],
            [
                0.011795512995276905,
                -0.039461437095008704,
                -0.15035684320812176,
                -0.10226942935357089,
                0.0014419482726203082,
            ],
        ),
        (
            [1.6271460971370635, -1.4018781981260555, -1.228625896396618, 1.5811539633955067, 1.329217404096556],
            [-0.8086910967697793, 0.8311495633881405, -1.0690166817997326, 0.9364308860840014, 0.07301924530301163],
            [3.3598138435171663, -0.26191605259742534, -1.8370875087749852, -2.9227014912547435, -4.927971262576274],
            [0.03138399835078425, 0.603796380937493, 0.22975536910135724, -0.06032352010693345, -0.0012521169327466167],
        ),
        (
            [-0.7821911456686383, 1.6549931800393094, -1.3756930854834872, -1.1719547966345454, -0.9885082539778223],
            [0.6470459793025887, -0.5457807530530503, 1.2496848645348835, 1.051390990131443, 0.6161142952865784],
            [1.2793781067432697, 1.880048792778358, 0.7412574730717267, -1.1118682925960544, 4.899794658231702],
            [0.038767647115517126, -0.739241508420847, -0.37129347070278423, -0.07062544136077914, 0.001316688658593],
        ),
        (
            [-0.14104591101404917, 1.5141258104112731, -0.2728457903581618, 0.47186778566832, 0.4667374121329573],
            [-1.8121980588189204, -0.21857363028624333, -0.041636117044548726, 1.7876495993201207, 1.0579818786981359],
            [-4.355091918880256, -4.397698779215888, -3.6134585963660104, -0.0420849898593989, 4.70048532438625],
            [
                -0.0426178494358254,
                -0.5997118648384204,
                -0.1554334878158068,
                0.0022366508056072976,
                0.0004927840425609214,
            ],
        ),
        (
            [-1.7656314064455285, -0.9953700067893244, 0.6927393256647987, -0.2586747038313819, 0.8878032046137774],
            [1.0954603130291778, 1.5202106541227112, 1.916998500264294, 0.8567386585402348, 0.9302957211116158],
            [-3.14844540660196, -2.7307657984943923, 4.811448686784006, -0.42829078979786495, -4.4285394241969005],
            [
                0.010423146439828451,
                -0.17940070114350198,
                -0.38216114968911014,
                -0.09524704758814967,
                -0.0018494890395640395,
            ],
        ),
        (
            [-0.6060384527820573, 0.6037067907006701, 0.2260319715568304, -1.073657158653709, -2.2078970130751774],
            [-0.7762821865526903, -1.6828528191114782, -0.8943023658870928, 0.6856541411530546, 0.27019692987673016],
            [-1.904236303811584, 1.9269596333145165, -3.4891919315972864, -0.8255017985892721, 1.6146587430299517],
            [-0.04251532745067759, -0.6724910385868742, -0.347087604559254, -0.12299069222897248, 0.001956085064425252],
        ),
    ];
    const PINOCCHIO_CRBA: [[f64; 5]; 5] = [
        [
            0.0044634686117211424,
            0.0002445437509480768,
            0.0001488753482885661,
            4.0468315785550533e-05,
            1.5281453052267602e-05,
        ],
        [
            0.0002445437509480768,
            0.023046322261565173,
            0.01313655017636908,
            0.0034722637092666746,
            3.493248217993316e-05,
        ],
        [
            0.0001488753482885661,
            0.01313655017636908,
            0.008002563108989225,
            0.0023025169515157274,
            2.326015641525615e-05,
        ],
        [
            4.0468315785550533e-05,
            0.0034722637092666746,
            0.0023025169515157274,
            0.0009931594275338338,
            1.0174684957431697e-05,
        ],
        [
            1.5281453052267602e-05,
            3.493248217993316e-05,
            2.326015641525615e-05,
            1.0174684957431697e-05,
            4.0570841769577e-05,
        ],
    ];

    /// The SO-101's inverse dynamics and mass matrix from its URDF's masses agree with
    /// Pinocchio's, which read the same file with its own parser, to 1e-9 (N m; kg m²).
    #[test]
    fn the_so101s_dynamics_agree_with_pinocchios() {
        use kinematics::dynamics::Dynamics;
        use kinematics::nalgebra::SVector;
        let chain = urdf::parse(SO101, TIP).unwrap().chain::<f64, 5>().unwrap();
        let m = masses(SO101, TIP).unwrap();
        let dynamics = Dynamics::new(m.links.clone().try_into().unwrap()).unwrap();
        for (q, v, a, tau) in PINOCCHIO_RNEA {
            let got = dynamics.inverse(&chain, &SVector::from(q), &SVector::from(v), &SVector::from(a));
            let worst = (got - SVector::from(tau)).abs().max();
            assert!(worst < 1e-9, "{got} against Pinocchio's {tau:?}");
        }
        let mass = dynamics.mass_matrix(&chain, &SVector::from(PINOCCHIO_RNEA[0].0));
        for (i, row) in PINOCCHIO_CRBA.iter().enumerate() {
            for (j, value) in row.iter().enumerate() {
                assert!((mass[(i, j)] - value).abs() < 1e-9, "M[{i}][{j}] = {} against {value}", mass[(i, j)]);
            }
        }
    }

    /// The file without any `<inertial>` element.
    fn without_inertials(text: &str) -> String {
        let mut out = String::new();
        let mut rest = text;
        while let Some(start) = rest.find("<inertial>") {
            out.push_str(&rest[..start]);
            let end = rest[start..].find("</inertial>").unwrap() + start + "</inertial>".len();
            rest = &rest[end..];
        }
        out.push_str(rest);
        out
    }
}
