// Legged robots on flat ground: rigid point contacts and impulses on a floating-base multibody,
// Crocoddyl's gait costs, and a whole contact schedule's rollouts and first-order expansion in one
// call. Twin of geoddp.models.contact.ContactDynamics (the node dynamics) and of
// geoddp.problem.legged.ContactProblem (the schedule's costs, the rollouts, linearise at order 1);
// same arithmetic, same Pinocchio calls, the same results to round-off (tests/test_contact_compiled.py).
//
// Contact node (contact_node.cpp): computeAllTerms, per foot the LOCAL Jacobian, velocity and
// classical acceleration with the Baumgarte drift a0 = alpha_f + Kp oRf^T p_f + Kd v_f (rotated to
// the world), Pinocchio's forwardDynamics with the world-aligned contact Jacobian (ABA with no
// foot on the ground), then semi-implicit Euler v+ = v + dt a, q+ = integrate(q, dt v+).
// Impulse node: Pinocchio's impulseDynamics (restitution 0), q+ = q. First derivatives by
// implicit differentiation of the KKT system (RNEA derivatives with the contact forces as
// external forces, the frames' velocity and acceleration derivatives), in z = (dq, dv, du).
//
// Exact second order (contact_second.cpp): the accelerations' (v+'s) and forces' second
// derivatives from the KKT system differentiated twice, the semi-implicit Euler step's chart terms
// (dynamics/reconstruction.hpp) and the costs' curvature, for the second-order expansion.
//
// Costs (contact_costs.cpp): the node's state regularisation, state-bounds barrier, CoM and
// swing-foot tracking, control regularisation and the friction-cone barrier on the contact
// forces; running contact nodes dt-scaled; gradients and Gauss-Newton Hessians in z.
//
// Every array is float64, row-major. nz = 2 nv + nu, nu = nv - 6 (the free flyer unactuated).
#pragma once

#include <pinocchio/multibody.hpp>

#include <Eigen/Core>
#include <map>
#include <memory>
#include <mutex>
#include <typeindex>
#include <utility>
#include <vector>

#include "dynamics/second_order_terms.hpp"
#include "runtime/arrays.hpp"
#include "runtime/parallel.hpp"

namespace geoddp {
namespace dyn {

// One node of a schedule: a contact node (feet on the ground) or an impulse node (feet touching
// down; no controls), with its cost targets.
struct ContactNode {
  bool impulse = false;
  std::vector<int> feet;
  bool has_com = false;
  Eigen::Vector3d com = Eigen::Vector3d::Zero();
  std::vector<int> swing;                    // frame ids of the foot-tracking terms
  std::vector<Eigen::Vector3d> swing_target; // their target positions, m
};

// The gait costs' weights (geoddp.problem.legged.GaitCosts).
struct GaitWeights {
  double com, friction_cone, foot, state, control, bounds, impulse_foot, impulse_state, impulse_control;
};

struct ContactSetup;

// The node loops' per-worker work (for_each_node's Extra: Pinocchio Data, model copies, scratch),
// kept between a setup's calls: building ContactSecondWork's Data and models took an eighth of the
// trot's exact expansion. check_out hands worker w's object of type T over (or makes one from the
// setup), check_in takes it back; two calls at once never share one (the second makes its own).
class WorkCache {
 public:
  template <class T>
  std::shared_ptr<T> check_out(const ContactSetup& s, int worker) {
    {
      std::lock_guard<std::mutex> lock(m_);
      auto it = slots_.find({std::type_index(typeid(T)), worker});
      if (it != slots_.end() && it->second) {
        std::shared_ptr<T> w = std::static_pointer_cast<T>(it->second);
        it->second.reset();
        return w;
      }
    }
    return std::make_shared<T>(s);
  }
  template <class T>
  void check_in(int worker, std::shared_ptr<T> w) {
    std::lock_guard<std::mutex> lock(m_);
    slots_[{std::type_index(typeid(T)), worker}] = std::move(w);
  }

 private:
  std::mutex m_;
  std::map<std::pair<std::type_index, int>, std::shared_ptr<void>> slots_;
};

// A whole problem: the robot, its contact model, the schedule (H running nodes then the terminal
// node) and the costs' data. Filled once (bind_contact.cpp) and read-only afterwards; `works` keeps
// the node loops' per-worker work between calls.
struct ContactSetup {
  const pinocchio::Model* model = nullptr;
  double dt = 0.0, Kp = 0.0, Kd = 0.0, impulse_damping = 0.0;
  std::vector<ContactNode> nodes;  // H + 1: the running nodes, then the terminal node
  GaitWeights w{};
  Eigen::VectorXd q0, v0;
  Eigen::VectorXd w_state, w_impulse, lb, ub;  // (2 nv): weights (squared) and state bounds
  Eigen::VectorXd q_ref, v_ref, q_neutral;
  RowMat cone_A;                               // (r, 3): the linearised friction cone
  Eigen::VectorXd cone_lb, cone_ub;            // (r)
  std::shared_ptr<WorkCache> works = std::make_shared<WorkCache>();
  int horizon() const { return (int)nodes.size() - 1; }
  int nv() const { return model->nv; }
  int nu() const { return model->nv - 6; }
};

// One node evaluated: next state, forces in the world frame (3 per foot), the accelerations acc
// (contact node; empty at an impulse node), and with derivatives Fz (2 nv, nz) of (q+, v+) in the
// tangent at (q+, v+), Lz (3 nc, nz) of the forces and Az (nv, nz) of the accelerations (contact
// node) or of v+ (impulse node): the Python NodeEval's fields.
struct ContactEval {
  Eigen::VectorXd q_next, v_next, forces, acc;
  RowMat Fz, Lz, Az;
};

// A node's scratch: a Pinocchio Data and the per-foot terms.
struct ContactWork {
  pinocchio::Data data;
  explicit ContactWork(const pinocchio::Model& model) : data(model) {}
};

// The node dynamics (contact_node.cpp).
void contact_node(const ContactSetup& s, ContactWork& w, const ContactNode& node, const Eigen::VectorXd& q,
                  const Eigen::VectorXd& v, const Eigen::VectorXd& u, bool derivatives, ContactEval& ev);
void impulse_node(const ContactSetup& s, ContactWork& w, const ContactNode& node, const Eigen::VectorXd& q,
                  const Eigen::VectorXd& v, bool derivatives, ContactEval& ev);

// Node k's cost (k = H: the terminal node, ev unused) at (q, v, u); with derivatives its gradient g
// (nz) and Gauss-Newton Hessian Hs (nz, nz) (contact_costs.cpp).
double contact_node_cost(const ContactSetup& s, ContactWork& w, int k, const Eigen::VectorXd& q,
                         const Eigen::VectorXd& v, const Eigen::VectorXd& u, const ContactEval* ev,
                         bool derivatives, Eigen::VectorXd& g, RowMat& Hs);

// Node k (< H) evaluated: its dynamics, then its cost (contact_trajectory.cpp).
double contact_step(const ContactSetup& s, ContactWork& w, int k, const Eigen::VectorXd& q, const Eigen::VectorXd& v,
                    const Eigen::VectorXd& u, bool derivatives, ContactEval& ev, Eigen::VectorXd& g, RowMat& Hs);

// The node loop of the whole-trajectory kernels (node-parallel): per worker an Extra(s) (the
// kernel's own work and scratch, with its ContactWork at node_work()), kept in s.works between
// calls; every node k = 0 .. H at (Q[k], V[k]) (and U[k],
// k < H) evaluated, with derivatives if `derivatives`: the terminal's cost into costs[H], then
// terminal(q, v, g, Hs, extra); a running node (contact_step) into costs[k], then
// running(k, q, v, ev, g, Hs, extra).
template <class Extra, class Running, class Terminal>
inline void for_each_node(const ContactSetup& s, const double* Q, const double* V, const double* U, int threads,
                          bool derivatives, double* costs, Running&& running, Terminal&& terminal) {
  const pinocchio::Model& m = *s.model;
  const int H = s.horizon(), nq = m.nq, nv = m.nv, nu = s.nu();
  CMatMap Qm(Q, H + 1, nq), Vm(V, H + 1, nv), Um(U, H, nu);
  parallel_for(H + 1, threads, [&](int b, int e, int worker) {
    std::shared_ptr<Extra> kept = s.works->check_out<Extra>(s, worker);
    Extra& extra = *kept;
    ContactWork& w = extra.node_work();
    ContactEval ev;
    Eigen::VectorXd g, q(nq), v(nv), u(nu);
    RowMat Hs;
    for (int k = b; k < e; ++k) {
      q = Qm.row(k).transpose();
      v = Vm.row(k).transpose();
      if (k == H) {
        costs[k] = contact_node_cost(s, w, H, q, v, Eigen::VectorXd::Zero(nu), nullptr, derivatives, g, Hs);
        terminal(q, v, g, Hs, extra);
        continue;
      }
      u = Um.row(k).transpose();
      costs[k] = contact_step(s, w, k, q, v, u, derivatives, ev, g, Hs);
      running(k, q, v, ev, g, Hs, extra);
    }
    s.works->check_in<Extra>(worker, std::move(kept));
  });
}

// Open-loop rollout from (q0, v0): U (H, nu) (the impulse rows act on nothing) -> Q (H+1, nq),
// V (H+1, nv), costs (H+1) (each node's cost, the terminal's last).
void contact_rollout(const ContactSetup& s, const double* U, double* Q, double* V, double* costs);

// The forward pass u = u_bar - gamma k - K zeta at contact nodes (zero controls at impulse nodes),
// zeta = (difference(q_bar, q), v - v_bar): writes Qout, Vout, Uout, costs; false (and stops) as soon
// as a state is non-finite.
bool contact_rollout_closed_loop(const ContactSetup& s, const double* Qbar, const double* Vbar, const double* Ubar,
                                 const double* kff, const double* K, double gamma, double* Qout, double* Vout,
                                 double* Uout, double* costs);

// Each node's cost along (Q, V, U).
void contact_costs(const ContactSetup& s, const double* Q, const double* V, const double* U, int threads,
                   double* costs);

// The first-order expansion along (Q, V, U): Phi (H, n, n), B (H, n, nu), the running costs'
// gradients lx (H, n), lu (H, nu) and Gauss-Newton Hessians lxx (H, n, n), lux (H, nu, n),
// luu (H, nu, nu), the terminal's lfx (n), lfxx (n, n), and the costs (H+1). Node-parallel.
void contact_linearise(const ContactSetup& s, const double* Q, const double* V, const double* U, int threads,
                       double* Phi, double* B, double* lx, double* lu, double* lxx, double* lux, double* luu,
                       double* lfx, double* lfxx, double* costs);

// Node k's first-order outputs, as contact_linearise and contact_linearise_second lay them out:
// Phi (n, n) and B (n, nu) from ev.Fz; the cost's gradient g (nz) and Hessian Hs (nz, nz) into
// lx (n), lu (nu), lxx (n, n), lux (nu, n), luu (nu, nu), each at node k's offset.
void store_node_expansion(int k, int n, int nu, const ContactEval& ev, const Eigen::VectorXd& g, const RowMat& Hs,
                          double* Phi, double* B, double* lx, double* lu, double* lxx, double* lux, double* luu);
// The terminal node's: lfx (n) = g's head, lfxx (n, n) = Hs's top-left block.
void store_terminal_expansion(int n, const Eigen::VectorXd& g, const RowMat& Hs, double* lfx, double* lfxx);

// ------------------------------------------------------------------ exact second order (contact_second.cpp)
// A worker's models for the second order: the robot without gravity and per foot frame a massless
// copy carrying a unit point mass at the frame's origin (built for a setup's feet and swing feet).
struct ContactSecondWork;

// Node (q, v) evaluated with derivatives as ev: Y (nv + 3 nc, nz * nz), the exact second
// derivatives (symmetric chart Hessians in z, row-major (nz, nz) per row) of the node's
// accelerations a (contact node) or v+ (impulse node), then of its world forces (3 per foot), by
// differentiating the KKT system twice (ContactDynamics.contact_second / impulse_second). Without
// `forces`, only Y's first nv rows are computed (the rest left unset).
void contact_node_second(const ContactSetup& s, ContactSecondWork& w, const ContactNode& node, const Eigen::VectorXd& q,
                         const Eigen::VectorXd& v, const ContactEval& ev, RowMat& Y, bool forces);

// Whether a friction-cone barrier of the running node is active at ev's forces (its cost then has
// the forces' curvature).
bool cone_active(const ContactSetup& s, const ContactNode& node, const ContactEval& ev);

// The friction-cone barrier's weights on the KKT rows wy (ny: zero on the first nv, friction_cone dt
// A^T excess on each active foot's three force rows), so that the barrier's curvature through the
// forces is sum_r wy_r y''_r; whether any foot's barrier is active.
bool cone_weights(const ContactSetup& s, const ContactNode& node, const ContactEval& ev, Eigen::VectorXd& wy);

// Add to Hs (nz, nz), node k's Gauss-Newton Hessian at (q, v) from contact_node_cost, the
// residuals' curvature: the exact Hessian (ContactProblem._cost_hessian). ev and Y (from
// contact_node_second, its force rows computed wherever a friction-cone barrier is active): a
// running node's; null at the terminal node (k = H).
void contact_cost_curvature(const ContactSetup& s, ContactSecondWork& w, int k, const Eigen::VectorXd& q,
                            const Eigen::VectorXd& v, const ContactEval* ev, const RowMat* Y, RowMat& Hs);

// The exact second-order expansion along (Q, V, U), ContactProblem.linearise(order=2): Phi, B,
// lx, lu, lfx and the costs as contact_linearise; Theta (H, n, n, n), Gamma (H, n, n, nu),
// Xi (H, n, nu, nu) of the semi-implicit Euler step with the KKT system's second derivatives; the
// exact cost Hessians lxx, lux, luu, lfxx. Node-parallel.
void contact_linearise_second(const ContactSetup& s, const double* Q, const double* V, const double* U, int threads,
                              double* Phi, double* B, double* Theta, double* Gamma, double* Xi, double* lx, double* lu,
                              double* lxx, double* lux, double* luu, double* lfx, double* lfxx, double* costs);

// contact_linearise_second with the dynamics' second order left factored in t (SecondOrderTerms,
// contact = true: per node the RNEA recursion's mu-free terms of the robot, each foot's point and
// force, the feet's rows of E_ss and Pqa on their chains, dy/dz and the KKT inverse's first nv rows, and
// the reconstruction's group blocks), contracted with V_x' in the backward pass (riccati/contracted.hpp) instead of
// forming Theta, Gamma, Xi; every other output as contact_linearise_second's. Node-parallel.
void contact_linearise_contracted(const ContactSetup& s, const double* Q, const double* V, const double* U, int threads,
                                  double* Phi, double* B, double* lx, double* lu, double* lxx, double* lux, double* luu,
                                  double* lfx, double* lfxx, double* costs, SecondOrderTerms& t);

// Node k (< H: its dynamics' Y as contact_node_second, and the exact cost Hessian; k = H: Y empty
// and the terminal's exact Hessian) at (q, v, u). For the tests.
void contact_node_second_at(const ContactSetup& s, int k, const Eigen::VectorXd& q, const Eigen::VectorXd& v,
                            const Eigen::VectorXd& u, RowMat& Y, RowMat& Hs);

}  // namespace dyn
}  // namespace geoddp
