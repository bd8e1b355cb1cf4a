"""Lie groups over Pinocchio's operators: one interface, SO(3), SE(3) and products over joints.

Conventions (Pinocchio's): everything is right / local (body frame).

* ``exp``/``log`` are the group exponential and its inverse (``pin.exp3``, ``pin.log3``, ...).
* The *right Jacobian* ``Jr(x)`` satisfies ``exp(x + d) = exp(x) exp(Jr(x) d + O(d^2))``.
  For SO(3) it is ``pin.Jexp3`` and the paper's ``dexp_{-x}``; its inverse is ``pin.Jlog3(exp3(x))``.
* ``Ad(R) = R`` for SO(3); ``ad(x) = hat(x)``.
* SE(3) twists are ``[linear; angular]`` (Pinocchio's Motion order).

The closed forms have Taylor branches chosen so that neither cancellation nor truncation error
exceeds ~1e-15 relative anywhere in [0, pi]: they never return NaN near the identity, unlike
``pin.Hlog3``. Batched versions take (N, d) arrays.

Modules:

* :mod:`.group`   the minimal interface (:class:`Group`) every non-commutative group implements;
* :mod:`.so3`     :class:`SO3`, ``hat``, ``vee``;
* :mod:`.se3`     :class:`SE3` (exact right Jacobian where Pinocchio 4.1's loses up to 3e-5);
* :mod:`.product` the configuration space of a Pinocchio model as a product of joint groups
  (:class:`JointGroup`, :func:`joint_groups`, block Ad / Jr / Jr^-1 / dJr / bracket tensors,
  :func:`difference`), and TSO(3) = SO(3) x R^3 (:class:`TSO3`) as its one-body instance.

The exact second-order reconstruction eta+ = Ad_A eta + Jr rho + 1/2 dJr[rho] rho
+ 1/2 [Ad_A eta, Jr rho], for any product group, is :func:`geoddp.models.integrators.expand`.
"""
from __future__ import annotations

from .group import Group
from .product import (
    KINDS,
    NONCOMMUTATIVE,
    SO3_ROOT,
    TSO3,
    JointGroup,
    block_Ad_Jr,
    block_Jr_inv,
    difference,
    difference_jacobian,
    group_second_order_tensors,
    joint_groups,
    second_order_tensors,
)
from .se3 import SE3
from .so3 import SO3, hat, vee

__all__ = [
    "Group", "SO3", "SE3", "TSO3", "hat", "vee", "KINDS", "NONCOMMUTATIVE", "SO3_ROOT", "JointGroup",
    "joint_groups", "difference", "difference_jacobian", "block_Ad_Jr", "block_Jr_inv",
    "group_second_order_tensors", "second_order_tensors",
]
