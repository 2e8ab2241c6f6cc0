//! `Robot` and `BaseParameters`: the model's algorithms on numpy batches, one method each.

use std::sync::Arc;

use arash_core::base_parameters::BaseParameterOptions;
use arash_core::{self as core, BaseParameters as CoreBase, CoulombShape, Model};
use numpy::{PyArrayDyn, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::batching::{batched, fill, row, Scratch};
use crate::convert::{batch, matrix_out, same_length, to_numpy, value_error};

/// A robot model: kinematic tree, mimic couplings, CAD parameters.
#[pyclass(module = "arash._arash", frozen)]
pub(crate) struct Robot {
    pub(crate) model: Arc<Model>,
    /// The URDF text the model was built from (identified models embed it).
    pub(crate) urdf: Arc<str>,
    /// The identifiable base parameters (weak regrouped) and the exact ones, computed on first use.
    pub(crate) fitted_base: [std::sync::OnceLock<CoreBase>; 2],
}

impl Robot {
    pub(crate) fn params_or_cad(&self, params: Option<PyReadonlyArrayDyn<'_, f64>>) -> PyResult<Vec<f64>> {
        match params {
            None => Ok(self.model.cad_parameters()),
            Some(p) => {
                let b = batch("params", &p, self.model.num_params())?;
                if !b.single {
                    return Err(PyValueError::new_err(format!(
                        "params must have shape ({},)",
                        self.model.num_params()
                    )));
                }
                Ok(b.values)
            }
        }
    }
}

#[pymethods]
impl Robot {
    /// Load a robot from a URDF file. Its Coulomb laws are left to the data (identification and
    /// the diagnosis choose each joint's friction velocity) unless declared: `coulomb_epsilon`
    /// (rad/s or m/s) declares tanh(q̇/ε) on every joint, `friction_velocities` one law per joint
    /// (a velocity v of tanh(q̇/v), or None for sign(q̇)). What the file declares that loads but
    /// deserves a look (a link with only semidefinite inertia) is raised as a `UserWarning`
    /// and kept in `warnings`.
    #[staticmethod]
    #[pyo3(signature = (path, coulomb_epsilon=None, friction_velocities=None))]
    fn from_urdf(
        py: Python<'_>,
        path: std::path::PathBuf,
        coulomb_epsilon: Option<f64>,
        friction_velocities: Option<Vec<Option<f64>>>,
    ) -> PyResult<Self> {
        let text = std::fs::read_to_string(&path)
            .map_err(|source| core::UrdfError::Io { path: path.display().to_string(), source })
            .map_err(value_error)?;
        let robot = Self::from_text(&text, DeclaredLaws { coulomb_epsilon, friction_velocities })?;
        for warning in &robot.model.warnings {
            let category = py.get_type::<pyo3::exceptions::PyUserWarning>();
            PyErr::warn(py, &category, &std::ffi::CString::new(format!("{}: {warning}", path.display()))?, 1)?;
        }
        Ok(robot)
    }

    /// What the URDF declared that loads but deserves a look, one line each.
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.model.warnings.iter().map(ToString::to_string).collect()
    }

    /// The same as data, one dict each: its `code`, its figures and its `text`.
    #[getter]
    fn concerns<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, pyo3::types::PyDict>>> {
        self.model
            .warnings
            .iter()
            .map(|warning| {
                let d = pyo3::types::PyDict::new(py);
                match warning {
                    core::ModelWarning::SemidefiniteInertia { link, eigenvalues } => {
                        d.set_item("code", "semidefinite_inertia")?;
                        d.set_item("link", link)?;
                        d.set_item("eigenvalues", eigenvalues.to_vec())?;
                    }
                }
                d.set_item("text", warning.to_string())?;
                Ok(d)
            })
            .collect()
    }

    /// The bundled ARASH:ASiST reconstruction.
    #[staticmethod]
    #[pyo3(signature = (coulomb_epsilon=None, friction_velocities=None))]
    fn arash_asist(coulomb_epsilon: Option<f64>, friction_velocities: Option<Vec<Option<f64>>>) -> PyResult<Self> {
        Self::from_text(core::ARASH_ASIST_URDF, DeclaredLaws { coulomb_epsilon, friction_velocities })
    }

    /// Each joint's friction velocity v of its Coulomb law tanh(q̇/v) (None: sign(q̇)).
    #[getter]
    fn friction_velocities(&self) -> Vec<Option<f64>> {
        self.model.coulomb_laws.velocities()
    }

    /// Whether the Coulomb laws are declared (`coulomb_epsilon`, `friction_velocities`, or a model
    /// file's) rather than left to the data.
    #[getter]
    fn coulomb_laws_declared(&self) -> bool {
        self.model.coulomb_laws.is_declared()
    }

    #[getter]
    fn dof(&self) -> usize {
        self.model.dof()
    }

    #[getter]
    fn num_params(&self) -> usize {
        self.model.num_params()
    }

    #[getter]
    fn name(&self) -> String {
        self.model.name.clone()
    }

    /// Actuated joint names, in the order of q.
    fn joint_names(&self) -> Vec<String> {
        self.model.joint_names()
    }

    /// Moving body (link) names, in parameter order.
    fn body_names(&self) -> Vec<String> {
        self.model.bodies.iter().map(|b| b.name.clone()).collect()
    }

    /// `(lower, upper)` position limits per actuated joint (rad or m).
    fn position_limits(&self) -> Vec<(f64, f64)> {
        self.model.position_limits()
    }

    /// Speed limit per actuated joint (rad/s or m/s).
    fn velocity_limits(&self) -> Vec<f64> {
        self.model.joints.iter().map(|j| j.velocity).collect()
    }

    fn parameter_names(&self) -> Vec<String> {
        self.model.parameter_names()
    }

    fn cad_parameters<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        to_numpy(py, self.model.cad_parameters(), false, self.model.num_params(), &[])
    }

    /// The mimic coupling G (bodies × dof): tree joint rates are G q̇.
    fn coupling_matrix<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let nb = self.model.bodies.len();
        to_numpy(py, self.model.coupling_matrix(), false, nb, &[self.model.dof()])
    }

    /// Y(q, q̇, q̈): (N, dof) in, (N, dof, P) out. Pass a C-contiguous float64 `out` of that
    /// shape to reuse its memory (large batches spend much of their time touching fresh pages).
    #[pyo3(signature = (q, qd, qdd, *, out=None))]
    fn regressor<'py>(
        &self,
        py: Python<'py>,
        q: PyReadonlyArrayDyn<'py, f64>,
        qd: PyReadonlyArrayDyn<'py, f64>,
        qdd: PyReadonlyArrayDyn<'py, f64>,
        out: Option<Bound<'py, PyArrayDyn<f64>>>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let (m, n, p) = (&*self.model, self.model.dof(), self.model.num_params());
        let (q, qd, qdd) = (batch("q", &q, n)?, batch("qd", &qd, n)?, batch("qdd", &qdd, n)?);
        let count = same_length(&[("q", &q), ("qd", &qd), ("qdd", &qdd)])?;
        let eval = |s: &mut Scratch, i: usize, o: &mut [f64]| {
            core::regressor(m, &mut s.data, row(&q, i, n), row(&qd, i, n), row(&qdd, i, n), o)
        };
        let Some(array) = out else {
            return batched(py, m, count, q.single, &[n, p], eval);
        };
        let expected: Vec<usize> = if q.single { vec![n, p] } else { vec![count, n, p] };
        if array.shape() != expected.as_slice() {
            return Err(PyValueError::new_err(format!("out must have shape {expected:?}, got {:?}", array.shape())));
        }
        fill(py, m, &array, n * p, eval)?;
        Ok(array)
    }

    /// Y_S(q, q̇, q̇_r, q̈_r): (N, dof) each, (N, dof, P) out.
    fn slotine_li_regressor<'py>(
        &self,
        py: Python<'py>,
        q: PyReadonlyArrayDyn<'py, f64>,
        qd: PyReadonlyArrayDyn<'py, f64>,
        qd_r: PyReadonlyArrayDyn<'py, f64>,
        qdd_r: PyReadonlyArrayDyn<'py, f64>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let (m, n, p) = (&*self.model, self.model.dof(), self.model.num_params());
        let (q, qd) = (batch("q", &q, n)?, batch("qd", &qd, n)?);
        let (qd_r, qdd_r) = (batch("qd_r", &qd_r, n)?, batch("qdd_r", &qdd_r, n)?);
        let count = same_length(&[("q", &q), ("qd", &qd), ("qd_r", &qd_r), ("qdd_r", &qdd_r)])?;
        batched(py, m, count, q.single, &[n, p], |s, i, o| {
            core::slotine_li_regressor(
                m,
                &mut s.data,
                row(&q, i, n),
                row(&qd, i, n),
                row(&qd_r, i, n),
                row(&qdd_r, i, n),
                o,
            )
        })
    }

    /// τ = Y(q, q̇, q̈) π: (N, dof) out. `params` defaults to the CAD values.
    #[pyo3(signature = (q, qd, qdd, params=None))]
    fn inverse_dynamics<'py>(
        &self,
        py: Python<'py>,
        q: PyReadonlyArrayDyn<'py, f64>,
        qd: PyReadonlyArrayDyn<'py, f64>,
        qdd: PyReadonlyArrayDyn<'py, f64>,
        params: Option<PyReadonlyArrayDyn<'py, f64>>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let (m, n) = (&*self.model, self.model.dof());
        let pi = self.params_or_cad(params)?;
        let (q, qd, qdd) = (batch("q", &q, n)?, batch("qd", &qd, n)?, batch("qdd", &qdd, n)?);
        let count = same_length(&[("q", &q), ("qd", &qd), ("qdd", &qdd)])?;
        batched(py, m, count, q.single, &[n], |s, i, o| {
            core::inverse_dynamics(m, &mut s.data, row(&q, i, n), row(&qd, i, n), row(&qdd, i, n), &pi, o)
        })
    }

    /// M(q): (N, dof, dof) out.
    #[pyo3(signature = (q, params=None))]
    fn mass_matrix<'py>(
        &self,
        py: Python<'py>,
        q: PyReadonlyArrayDyn<'py, f64>,
        params: Option<PyReadonlyArrayDyn<'py, f64>>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let (m, n) = (&*self.model, self.model.dof());
        let pi = self.params_or_cad(params)?;
        let q = batch("q", &q, n)?;
        batched(py, m, q.n, q.single, &[n, n], |s, i, o| core::mass_matrix(m, &mut s.data, row(&q, i, n), &pi, o))
    }

    /// C(q, q̇) from the Christoffel symbols: (N, dof, dof) out.
    #[pyo3(signature = (q, qd, params=None))]
    fn coriolis_matrix<'py>(
        &self,
        py: Python<'py>,
        q: PyReadonlyArrayDyn<'py, f64>,
        qd: PyReadonlyArrayDyn<'py, f64>,
        params: Option<PyReadonlyArrayDyn<'py, f64>>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let (m, n) = (&*self.model, self.model.dof());
        let pi = self.params_or_cad(params)?;
        let (q, qd) = (batch("q", &q, n)?, batch("qd", &qd, n)?);
        let count = same_length(&[("q", &q), ("qd", &qd)])?;
        batched(py, m, count, q.single, &[n, n], |s, i, o| {
            core::coriolis_matrix(m, &mut s.data, row(&q, i, n), row(&qd, i, n), &pi, o)
        })
    }

    /// g(q): (N, dof) out.
    #[pyo3(signature = (q, params=None))]
    fn gravity<'py>(
        &self,
        py: Python<'py>,
        q: PyReadonlyArrayDyn<'py, f64>,
        params: Option<PyReadonlyArrayDyn<'py, f64>>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let (m, n) = (&*self.model, self.model.dof());
        let pi = self.params_or_cad(params)?;
        let q = batch("q", &q, n)?;
        batched(py, m, q.n, q.single, &[n], |s, i, o| core::gravity_torque(m, &mut s.data, row(&q, i, n), &pi, o))
    }

    /// q̈ = M⁻¹(τ − C q̇ − g − friction − elastic): (N, dof) out.
    #[pyo3(signature = (q, qd, tau, params=None))]
    fn forward_dynamics<'py>(
        &self,
        py: Python<'py>,
        q: PyReadonlyArrayDyn<'py, f64>,
        qd: PyReadonlyArrayDyn<'py, f64>,
        tau: PyReadonlyArrayDyn<'py, f64>,
        params: Option<PyReadonlyArrayDyn<'py, f64>>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let (m, n) = (&*self.model, self.model.dof());
        let pi = self.params_or_cad(params)?;
        let (q, qd, tau) = (batch("q", &q, n)?, batch("qd", &qd, n)?, batch("tau", &tau, n)?);
        let count = same_length(&[("q", &q), ("qd", &qd), ("tau", &tau)])?;
        let failure = std::sync::Mutex::new(None);
        let out = batched(py, m, count, q.single, &[n], |s, i, o| {
            if let Err(e) =
                core::forward_dynamics(m, &mut s.data, row(&q, i, n), row(&qd, i, n), row(&tau, i, n), &pi, o)
            {
                failure.lock().expect("no panics hold this lock").get_or_insert(format!("sample {i}: {e}"));
            }
        })?;
        if let Some(message) = failure.into_inner().expect("no panics hold this lock") {
            return Err(PyValueError::new_err(message));
        }
        Ok(out)
    }

    /// The base parameters (identifiable combinations), from `samples` random states.
    /// None keeps the default of each; `regroup_weak` regroups the combinations no trajectory
    /// within the limits separates (then `Y π = Y_r β` only on such trajectories, to their residual).
    #[pyo3(signature = (samples=None, seed=None, regroup_weak=false))]
    fn base_parameters(
        &self,
        samples: Option<usize>,
        seed: Option<u64>,
        regroup_weak: bool,
    ) -> PyResult<BaseParameters> {
        let defaults = BaseParameterOptions::default();
        let options = BaseParameterOptions {
            samples: samples.unwrap_or(defaults.samples),
            seed: seed.unwrap_or(defaults.seed),
            ..defaults
        };
        let options = if regroup_weak { options.identifiable() } else { options };
        let base = CoreBase::compute(&self.model, &options).map_err(|e| PyValueError::new_err(e.to_string()))?;
        Ok(BaseParameters { model: Arc::clone(&self.model), base })
    }

    fn __repr__(&self) -> String {
        format!(
            "Robot('{}', dof={}, bodies={}, params={})",
            self.model.name,
            self.model.dof(),
            self.model.bodies.len(),
            self.model.num_params()
        )
    }
}

impl Robot {
    /// The base parameters fitted by default (`BaseParameterOptions::fitted`), cached: they
    /// depend only on the model. `keep_weak` keeps those no trajectory within the limits separates.
    pub(crate) fn fitted_base(&self, keep_weak: bool) -> PyResult<&CoreBase> {
        self.cached_base(BaseParameterOptions::fitted(keep_weak))
    }

    /// The base parameters the diagnosis fits without a model (`BaseParameterOptions::diagnosed`).
    pub(crate) fn diagnosed_base(&self) -> PyResult<&CoreBase> {
        self.cached_base(BaseParameterOptions::diagnosed())
    }

    /// The base parameters of `options`, cached by the one setting the front ends vary: whether
    /// the weak ones are regrouped.
    fn cached_base(&self, options: BaseParameterOptions) -> PyResult<&CoreBase> {
        let cell = &self.fitted_base[usize::from(options.weak_tolerance == 0.0)];
        if let Some(base) = cell.get() {
            return Ok(base);
        }
        let base = CoreBase::compute(&self.model, &options).map_err(value_error)?;
        Ok(cell.get_or_init(|| base))
    }

    /// The fitted base parameters whose columns are `independent` (a model file's), weak kept or not.
    pub(crate) fn base_of(&self, independent: &[usize]) -> PyResult<&CoreBase> {
        for keep_weak in [false, true] {
            let base = self.fitted_base(keep_weak)?;
            if base.independent == independent {
                return Ok(base);
            }
        }
        self.fitted_base(false)
    }

    pub(crate) fn from_text(urdf: &str, declared: DeclaredLaws) -> PyResult<Self> {
        let mut model = core::parse_urdf(urdf).map_err(value_error)?;
        if let Some(laws) = declared.laws(model.dof())? {
            model.coulomb_laws = laws;
        }
        Ok(Self::of_model(model, urdf))
    }

    /// The robot of a model file: its URDF, with the Coulomb laws the file was fitted with.
    pub(crate) fn of_file(file: &core::model_file::ModelFile) -> PyResult<Self> {
        let mut model = core::parse_urdf(&file.urdf).map_err(value_error)?;
        model.coulomb_laws = file.coulomb_laws();
        Ok(Self::of_model(model, &file.urdf))
    }

    fn of_model(model: Model, urdf: &str) -> Self {
        Self { model: Arc::new(model), urdf: Arc::from(urdf), fitted_base: Default::default() }
    }
}

/// The Coulomb laws a user may declare when loading a robot: one width for all joints, or one law
/// per joint; neither leaves them to the data.
#[derive(Default)]
pub(crate) struct DeclaredLaws {
    pub(crate) coulomb_epsilon: Option<f64>,
    pub(crate) friction_velocities: Option<Vec<Option<f64>>>,
}

impl DeclaredLaws {
    fn laws(self, dof: usize) -> PyResult<Option<core::CoulombLaws>> {
        match (self.coulomb_epsilon, self.friction_velocities) {
            (Some(_), Some(_)) => Err(PyValueError::new_err(
                "give coulomb_epsilon (one law for every joint) or friction_velocities, not both",
            )),
            (Some(epsilon), None) => {
                let shape = CoulombShape::tanh(epsilon).ok_or_else(|| {
                    PyValueError::new_err(format!("coulomb_epsilon must be positive and finite, got {epsilon}"))
                })?;
                Ok(Some(core::CoulombLaws::uniform(shape, dof)))
            }
            (None, Some(velocities)) => {
                if velocities.len() != dof {
                    return Err(PyValueError::new_err(format!(
                        "friction_velocities needs {dof} values, one per joint (None for sign(q̇)); got {}",
                        velocities.len()
                    )));
                }
                core::CoulombLaws::of_velocities(&velocities).map(Some).map_err(|(k, v)| {
                    PyValueError::new_err(format!(
                        "friction_velocities[{k}] must be positive and finite (None for sign(q̇)), got {v}"
                    ))
                })
            }
            (None, None) => Ok(None),
        }
    }
}

/// β = B π: the identifiable combinations of the standard parameters.
#[pyclass(module = "arash._arash", frozen)]
pub(crate) struct BaseParameters {
    pub(crate) model: Arc<Model>,
    pub(crate) base: CoreBase,
}

#[pymethods]
impl BaseParameters {
    /// Number of base parameters.
    #[getter]
    fn p(&self) -> usize {
        self.base.rank
    }

    /// B, shape (p, P).
    #[getter(B)]
    fn b<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        matrix_out(py, &self.base.b, self.base.num_params)
    }

    #[getter]
    fn names(&self) -> Vec<String> {
        self.base.names.clone()
    }

    #[getter]
    fn expressions(&self) -> Vec<String> {
        self.base.expressions.clone()
    }

    /// Indices of the standard parameters whose regressor columns form Y_r.
    #[getter]
    fn independent(&self) -> Vec<usize> {
        self.base.independent.clone()
    }

    /// The weak base parameters, regrouped because no trajectory within the limits separates them:
    /// `(name, residual, expression)` each (empty unless `regroup_weak=True`).
    #[getter]
    fn weak(&self) -> Vec<(String, f64, String)> {
        self.base.weak.iter().map(|w| (w.name.clone(), w.residual, w.expression.clone())).collect()
    }

    /// What the weak-parameter test found, as text.
    fn weak_report(&self) -> String {
        self.base.weak_report()
    }

    /// β = B π for a standard parameter vector.
    fn project<'py>(
        &self,
        py: Python<'py>,
        params: PyReadonlyArrayDyn<'py, f64>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let pi = batch("params", &params, self.base.num_params)?;
        if !pi.single {
            return Err(PyValueError::new_err(format!("params must have shape ({},)", self.base.num_params)));
        }
        let mut beta = vec![0.0; self.base.rank];
        self.base.project(&pi.values, &mut beta);
        to_numpy(py, beta, false, self.base.rank, &[])
    }

    /// Y_r(q, q̇, q̈): (N, dof) in, (N, dof, p) out, with Y π = Y_r β.
    fn reduced_regressor<'py>(
        &self,
        py: Python<'py>,
        q: PyReadonlyArrayDyn<'py, f64>,
        qd: PyReadonlyArrayDyn<'py, f64>,
        qdd: PyReadonlyArrayDyn<'py, f64>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let (m, n, rank) = (&*self.model, self.model.dof(), self.base.rank);
        let (q, qd, qdd) = (batch("q", &q, n)?, batch("qd", &qd, n)?, batch("qdd", &qdd, n)?);
        let count = same_length(&[("q", &q), ("qd", &qd), ("qdd", &qdd)])?;
        let base = &self.base;
        let bodies = core::regressor::bodies_of_columns(m, &base.independent);
        batched(py, m, count, q.single, &[n, rank], |s, i, o| {
            let (q, qd, qdd) = (row(&q, i, n), row(&qd, i, n), row(&qdd, i, n));
            core::regressor_of_bodies(m, &mut s.data, q, qd, qdd, Some(&bodies), &mut s.regressor);
            base.reduce(&s.regressor, o);
        })
    }

    fn __repr__(&self) -> String {
        format!("BaseParameters(p={}, P={}, weak={})", self.base.rank, self.base.num_params, self.base.weak.len())
    }
}
