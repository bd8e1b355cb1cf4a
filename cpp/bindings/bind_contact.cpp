// Bindings of the contact-schedule kernels (dynamics/contact.hpp): the class ContactKernel holds a
// problem (the robot, its contact model, the schedule and the costs' data) and runs its rollouts,
// node costs, first-order expansion, every node's first-order terms (the second-order expansion's
// input) and single nodes (for the tests' comparisons).
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <memory>
#include <string>

#include "bindings/bindings.hpp"
#include "bindings/checks.hpp"
#include "bindings/pin_model.hpp"
#include "dynamics/contact.hpp"
#include "runtime/parallel.hpp"

namespace geoddp {

namespace py = pybind11;
using bind::Arr;
using bind::check_shape;
using bind::empty;

namespace {

Eigen::VectorXd vec(const py::handle& o, long n, const char* name) {
  Arr a = py::cast<Arr>(o);
  check_shape(a, {n}, name);
  return Eigen::Map<const Eigen::VectorXd>(a.data(), n);
}

// The problem and a reference to the Python pin.Model it points into (kept alive with it).
struct ContactKernel {
  py::object model_ref;
  dyn::ContactSetup s;
};

Arr vec_array(const Eigen::VectorXd& x) {
  Arr a = empty({(py::ssize_t)x.size()});
  if (x.size()) Eigen::Map<Eigen::VectorXd>(a.mutable_data(), x.size()) = x;
  return a;
}

Arr mat_array(const RowMat& x) {
  Arr a = empty({(py::ssize_t)x.rows(), (py::ssize_t)x.cols()});
  if (x.size()) MatMap(a.mutable_data(), x.rows(), x.cols()) = x;
  return a;
}

std::unique_ptr<ContactKernel> make_kernel(py::object pm, double dt, double Kp, double Kd, double impulse_damping,
                                           const py::list& nodes, const Arr& weights, const Arr& q0, const Arr& v0,
                                           const Arr& w_state, const Arr& w_impulse, const Arr& lb, const Arr& ub,
                                           const Arr& q_ref, const Arr& v_ref, const Arr& q_neutral,
                                           const Arr& cone_A, const Arr& cone_lb, const Arr& cone_ub) {
  auto k = std::make_unique<ContactKernel>();
  k->model_ref = pm;
  const pinocchio::Model& model = geoddp::model_from_python(pm);
  dyn::ContactSetup& s = k->s;
  s.model = &model;
  const int nq = model.nq, nv = model.nv, nframes = (int)model.nframes;
  if (nv < 7) throw py::value_error("model: expected a free-flyer root and actuated joints");
  s.dt = dt;
  s.Kp = Kp;
  s.Kd = Kd;
  s.impulse_damping = impulse_damping;
  check_shape(weights, {9}, "weights");
  const double* w = weights.data();
  s.w = dyn::GaitWeights{w[0], w[1], w[2], w[3], w[4], w[5], w[6], w[7], w[8]};
  s.q0 = vec(q0, nq, "q0");
  s.v0 = vec(v0, nv, "v0");
  s.w_state = vec(w_state, 2 * nv, "w_state");
  s.w_impulse = vec(w_impulse, 2 * nv, "w_impulse");
  s.lb = vec(lb, 2 * nv, "lb");
  s.ub = vec(ub, 2 * nv, "ub");
  s.q_ref = vec(q_ref, nq, "q_ref");
  s.v_ref = vec(v_ref, nv, "v_ref");
  s.q_neutral = vec(q_neutral, nq, "q_neutral");
  check_shape(cone_A, {-1, 3}, "cone_A");
  const long r = cone_A.shape(0);
  s.cone_A = CMatMap(cone_A.data(), r, 3);
  s.cone_lb = vec(cone_lb, r, "cone_lb");
  s.cone_ub = vec(cone_ub, r, "cone_ub");
  auto frame = [&](const py::handle& o) {
    const int f = py::cast<int>(o);
    if (f < 0 || f >= nframes) throw py::value_error("nodes: frame id " + std::to_string(f) + " out of range");
    return f;
  };
  // each node: (impulse: bool, feet: [int], com: (3,) or None, swing: [(int, (3,))])
  for (const py::handle& o : nodes) {
    const py::tuple t = py::cast<py::tuple>(o);
    if (t.size() != 4) throw py::value_error("nodes: expected (impulse, feet, com, swing) tuples");
    dyn::ContactNode n;
    n.impulse = py::cast<bool>(t[0]);
    for (const py::handle& f : py::cast<py::sequence>(t[1])) n.feet.push_back(frame(f));
    if (!t[2].is_none()) {
      n.has_com = true;
      n.com = vec(t[2], 3, "nodes.com");
    }
    for (const py::handle& sw : py::cast<py::sequence>(t[3])) {
      const py::tuple p = py::cast<py::tuple>(sw);
      n.swing.push_back(frame(p[0]));
      n.swing_target.push_back(vec(p[1], 3, "nodes.swing"));
    }
    s.nodes.push_back(n);
  }
  if (s.nodes.size() < 2) throw py::value_error("nodes: expected the running nodes and the terminal node");
  return k;
}

// A trajectory's shapes for setup s: Q (H+1, nq), V (H+1, nv), U (H, nu).
void check_trajectory(const dyn::ContactSetup& s, const Arr& Q, const Arr& V, const Arr& U) {
  const int H = s.horizon();
  check_shape(Q, {H + 1, s.model->nq}, "Q");
  check_shape(V, {H + 1, s.nv()}, "V");
  check_shape(U, {H, s.nu()}, "U");
}

// The expansions' outputs for setup s (n = 2 nv): Phi (H, n, n), B (H, n, nu), lx, lu, lxx, lux,
// luu, lfx, lfxx, the node costs (H+1), and for the second order Theta (H, n, n, n),
// Gamma (H, n, n, nu), Xi (H, n, nu, nu).
struct ExpansionArrays {
  Arr Phi, B, Theta, Gamma, Xi, lx, lu, lxx, lux, luu, lfx, lfxx, c;
  ExpansionArrays(const dyn::ContactSetup& s, bool second) {
    const py::ssize_t H = s.horizon(), nu = s.nu(), n = 2 * s.nv();
    Phi = empty({H, n, n}), B = empty({H, n, nu}), lx = empty({H, n}), lu = empty({H, nu});
    lxx = empty({H, n, n}), lux = empty({H, nu, n}), luu = empty({H, nu, nu});
    lfx = empty({n}), lfxx = empty({n, n}), c = empty({H + 1});
    if (second) Theta = empty({H, n, n, n}), Gamma = empty({H, n, n, nu}), Xi = empty({H, n, nu, nu});
  }
};

}  // namespace

void bind_contact(py::module_& m) {
  py::class_<ContactKernel>(m, "ContactKernel",
                            "A contact schedule's problem in the compiled core: rollouts, node costs and the "
                            "first-order expansion (geoddp.models.contact_compiled builds it).")
      .def(py::init(&make_kernel), py::arg("model"), py::arg("dt"), py::arg("Kp"), py::arg("Kd"),
           py::arg("impulse_damping"), py::arg("nodes"), py::arg("weights"), py::arg("q0"), py::arg("v0"),
           py::arg("w_state"), py::arg("w_impulse"), py::arg("lb"), py::arg("ub"), py::arg("q_ref"),
           py::arg("v_ref"), py::arg("q_neutral"), py::arg("cone_A"), py::arg("cone_lb"), py::arg("cone_ub"))
      .def_property_readonly("horizon", [](const ContactKernel& k) { return k.s.horizon(); })
      .def(
          "rollout",
          [](const ContactKernel& k, const Arr& U) {
            const auto& s = k.s;
            const int H = s.horizon();
            check_shape(U, {H, s.nu()}, "U");
            Arr Q = empty({H + 1, s.model->nq}), V = empty({H + 1, s.nv()}), c = empty({H + 1});
            {
              py::gil_scoped_release nogil;
              dyn::contact_rollout(s, U.data(), Q.mutable_data(), V.mutable_data(), c.mutable_data());
            }
            return py::make_tuple(Q, V, c);
          },
          py::arg("U"), "Open-loop rollout: U (H, nu) -> Q (H+1, nq), V (H+1, nv), node costs (H+1).")
      .def(
          "rollout_closed_loop",
          [](const ContactKernel& k, const Arr& Qbar, const Arr& Vbar, const Arr& Ubar, const Arr& kff, const Arr& K,
             double gamma) -> py::object {
            const auto& s = k.s;
            const int H = s.horizon(), nq = s.model->nq, nv = s.nv(), nu = s.nu();
            check_shape(Qbar, {H + 1, nq}, "Q_bar");
            check_shape(Vbar, {H + 1, nv}, "V_bar");
            check_shape(Ubar, {H, nu}, "u_bar");
            check_shape(kff, {H, nu}, "k");
            check_shape(K, {H, nu, 2 * nv}, "K");
            Arr Q = empty({H + 1, nq}), V = empty({H + 1, nv}), U = empty({H, nu}), c = empty({H + 1});
            bool ok;
            {
              py::gil_scoped_release nogil;
              ok = dyn::contact_rollout_closed_loop(s, Qbar.data(), Vbar.data(), Ubar.data(), kff.data(), K.data(),
                                                    gamma, Q.mutable_data(), V.mutable_data(), U.mutable_data(),
                                                    c.mutable_data());
            }
            if (!ok) return py::none();
            return py::make_tuple(Q, V, U, c);
          },
          py::arg("Q_bar"), py::arg("V_bar"), py::arg("u_bar"), py::arg("k"), py::arg("K"), py::arg("gamma"),
          "Forward pass u = u_bar - gamma k - K zeta (zero at impulse nodes): (Q, V, U, node costs), or None "
          "if a state became non-finite.")
      .def(
          "costs",
          [](const ContactKernel& k, const Arr& Q, const Arr& V, const Arr& U, int threads) {
            const auto& s = k.s;
            check_trajectory(s, Q, V, U);
            Arr c = empty({s.horizon() + 1});
            {
              py::gil_scoped_release nogil;
              dyn::contact_costs(s, Q.data(), V.data(), U.data(), threads, c.mutable_data());
            }
            return c;
          },
          py::arg("Q"), py::arg("V"), py::arg("U"), py::arg("threads") = 0, "Each node's cost (H+1).")
      .def(
          "linearise",
          [](const ContactKernel& k, const Arr& Q, const Arr& V, const Arr& U, int threads) {
            const auto& s = k.s;
            check_trajectory(s, Q, V, U);
            ExpansionArrays o(s, false);
            {
              py::gil_scoped_release nogil;
              dyn::contact_linearise(s, Q.data(), V.data(), U.data(), threads, o.Phi.mutable_data(),
                                     o.B.mutable_data(), o.lx.mutable_data(), o.lu.mutable_data(),
                                     o.lxx.mutable_data(), o.lux.mutable_data(), o.luu.mutable_data(),
                                     o.lfx.mutable_data(), o.lfxx.mutable_data(), o.c.mutable_data());
            }
            return py::make_tuple(o.Phi, o.B, o.lx, o.lu, o.lxx, o.lux, o.luu, o.lfx, o.lfxx, o.c);
          },
          py::arg("Q"), py::arg("V"), py::arg("U"), py::arg("threads") = 0,
          "First-order expansion: (Phi, B, lx, lu, lxx, lux, luu, lfx, lfxx, node costs).")
      .def(
          "linearise_second",
          [](const ContactKernel& k, const Arr& Q, const Arr& V, const Arr& U, int threads) {
            const auto& s = k.s;
            check_trajectory(s, Q, V, U);
            ExpansionArrays o(s, true);
            {
              py::gil_scoped_release nogil;
              dyn::contact_linearise_second(s, Q.data(), V.data(), U.data(), threads, o.Phi.mutable_data(),
                                            o.B.mutable_data(), o.Theta.mutable_data(), o.Gamma.mutable_data(),
                                            o.Xi.mutable_data(), o.lx.mutable_data(), o.lu.mutable_data(),
                                            o.lxx.mutable_data(), o.lux.mutable_data(), o.luu.mutable_data(),
                                            o.lfx.mutable_data(), o.lfxx.mutable_data(), o.c.mutable_data());
            }
            return py::make_tuple(o.Phi, o.B, o.Theta, o.Gamma, o.Xi, o.lx, o.lu, o.lxx, o.lux, o.luu, o.lfx, o.lfxx,
                                  o.c);
          },
          py::arg("Q"), py::arg("V"), py::arg("U"), py::arg("threads") = 0,
          "Exact second-order expansion: (Phi, B, Theta, Gamma, Xi, lx, lu, lxx, lux, luu, lfx, lfxx, node costs), "
          "the cost Hessians exact.")
      .def(
          "linearise_contracted",
          [](const ContactKernel& k, const Arr& Q, const Arr& V, const Arr& U, int threads) {
            const auto& s = k.s;
            check_trajectory(s, Q, V, U);
            ExpansionArrays o(s, false);
            auto terms = std::make_shared<dyn::SecondOrderTerms>();
            {
              py::gil_scoped_release nogil;
              dyn::contact_linearise_contracted(s, Q.data(), V.data(), U.data(), threads, o.Phi.mutable_data(),
                                                o.B.mutable_data(), o.lx.mutable_data(), o.lu.mutable_data(),
                                                o.lxx.mutable_data(), o.lux.mutable_data(), o.luu.mutable_data(),
                                                o.lfx.mutable_data(), o.lfxx.mutable_data(), o.c.mutable_data(),
                                                *terms);
            }
            py::object t = py::cast(terms);
            t.attr("_model") = k.model_ref;  // the terms point into the model (as expansion_contracted's)
            return py::make_tuple(o.Phi, o.B, o.lx, o.lu, o.lxx, o.lux, o.luu, o.lfx, o.lfxx, o.c, t);
          },
          py::arg("Q"), py::arg("V"), py::arg("U"), py::arg("threads") = 0,
          "Exact second-order expansion with the dynamics' second order factored: (Phi, B, lx, lu, lxx, lux, luu, "
          "lfx, lfxx, node costs, SecondOrderTerms), every array as linearise_second's; the terms give "
          "sum_i Vx_i [[Theta_i, Gamma_i], [Gamma_i^T, Xi_i]] by contract(k, Vx) and feed the contracted passes.")
      .def(
          "node_second",
          [](const ContactKernel& k, int j, const Arr& q, const Arr& v, const Arr& u) {
            const auto& s = k.s;
            const int H = s.horizon(), nv = s.nv(), nu = s.nu(), nz = 2 * nv + nu;
            if (j < 0 || j > H) throw py::value_error("k: expected a node index in 0 .. H");
            const Eigen::VectorXd qq = vec(q, s.model->nq, "q"), vv = vec(v, nv, "v"), uu = vec(u, nu, "u");
            RowMat Y, Hs;
            {
              py::gil_scoped_release nogil;
              dyn::contact_node_second_at(s, j, qq, vv, uu, Y, Hs);
            }
            Arr Ya = empty({(py::ssize_t)Y.rows(), nz, nz});
            if (Y.size()) MatMap(Ya.mutable_data(), Y.rows(), Y.cols()) = Y;
            return py::make_tuple(Ya, mat_array(Hs));
          },
          py::arg("k"), py::arg("q"), py::arg("v"), py::arg("u"),
          "Node k at (q, v, u): (Y (nv + 3 nc, nz, nz): the exact second derivatives of its accelerations (contact "
          "node) or v+ (impulse node), then of its world forces; empty at the terminal node; the exact cost Hessian "
          "(nz, nz)).")
      .def(
          "evaluate",
          [](const ContactKernel& k, const Arr& Q, const Arr& V, const Arr& U, int threads) {
            const auto& s = k.s;
            const int H = s.horizon(), nq = s.model->nq, nv = s.nv(), nu = s.nu();
            check_trajectory(s, Q, V, U);
            std::vector<dyn::ContactEval> evs((size_t)H);
            std::vector<Eigen::VectorXd> gs((size_t)H + 1);
            std::vector<RowMat> Hss((size_t)H + 1);
            std::vector<double> costs((size_t)H + 1);
            {
              py::gil_scoped_release nogil;
              const double *Qd = Q.data(), *Vd = V.data(), *Ud = U.data();
              parallel_nodes(H + 1, threads, [&](int b, int e) {
                dyn::ContactWork w(*s.model);
                Eigen::VectorXd q(nq), v(nv), u(nu);
                for (int j = b; j < e; ++j) {
                  q = CVecMap(Qd + (size_t)j * nq, nq);
                  v = CVecMap(Vd + (size_t)j * nv, nv);
                  if (j == H) {
                    costs[(size_t)j] = dyn::contact_node_cost(s, w, H, q, v, Eigen::VectorXd::Zero(nu), nullptr, true,
                                                              gs[(size_t)j], Hss[(size_t)j]);
                    continue;
                  }
                  u = CVecMap(Ud + (size_t)j * nu, nu);
                  costs[(size_t)j] = dyn::contact_step(s, w, j, q, v, u, true, evs[(size_t)j], gs[(size_t)j],
                                                       Hss[(size_t)j]);
                }
              });
            }
            py::list out;
            for (int j = 0; j <= H; ++j) {
              py::dict d;
              d["cost"] = costs[(size_t)j];
              d["g"] = vec_array(gs[(size_t)j]);
              d["Hs"] = mat_array(Hss[(size_t)j]);
              if (j < H) {
                const dyn::ContactEval& ev = evs[(size_t)j];
                d["q_next"] = vec_array(ev.q_next);
                d["v_next"] = vec_array(ev.v_next);
                d["forces"] = vec_array(ev.forces);
                d["acc"] = s.nodes[(size_t)j].impulse ? py::object(py::none()) : py::object(vec_array(ev.acc));
                d["Fz"] = mat_array(ev.Fz);
                d["Lz"] = mat_array(ev.Lz);
                d["Az"] = mat_array(ev.Az);
              }
              out.append(d);
            }
            return out;
          },
          py::arg("Q"), py::arg("V"), py::arg("U"), py::arg("threads") = 0,
          "Every node along (Q, V, U) with first derivatives (node-parallel): H + 1 dicts of cost, g, Hs and, "
          "below the terminal node, q_next, v_next, forces, acc (None at an impulse node), Fz, Lz, Az.")
      .def(
          "node",
          [](const ContactKernel& k, int j, const Arr& q, const Arr& v, const Arr& u, bool derivatives) {
            const auto& s = k.s;
            const int H = s.horizon(), nv = s.nv(), nu = s.nu();
            if (j < 0 || j > H) throw py::value_error("k: expected a node index in 0 .. H");
            const Eigen::VectorXd qq = vec(q, s.model->nq, "q"), vv = vec(v, nv, "v"), uu = vec(u, nu, "u");
            dyn::ContactWork w(*s.model);
            dyn::ContactEval ev;
            Eigen::VectorXd g;
            RowMat Hs;
            double c;
            {
              py::gil_scoped_release nogil;
              if (j == H) c = dyn::contact_node_cost(s, w, H, qq, vv, Eigen::VectorXd::Zero(nu), nullptr, derivatives,
                                                     g, Hs);
              else c = dyn::contact_step(s, w, j, qq, vv, uu, derivatives, ev, g, Hs);
            }
            const auto arr = vec_array;
            const auto mat = mat_array;
            py::dict out;
            out["cost"] = c;
            if (j < H) {
              out["q_next"] = arr(ev.q_next);
              out["v_next"] = arr(ev.v_next);
              out["forces"] = arr(ev.forces);
            }
            if (derivatives) {
              out["g"] = arr(g);
              out["Hs"] = mat(Hs);
              if (j < H) {
                out["Fz"] = mat(ev.Fz);
                out["Lz"] = mat(ev.Lz);
                out["Az"] = mat(ev.Az);
              }
            }
            return out;
          },
          py::arg("k"), py::arg("q"), py::arg("v"), py::arg("u"), py::arg("derivatives") = false,
          "Node k at (q, v, u): a dict of cost and, below the terminal node, q_next, v_next, forces; with "
          "derivatives g, Hs and Fz, Lz, Az.");
}

}  // namespace geoddp
