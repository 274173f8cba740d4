"""Small trees for tests: a waist shared by two short arms (with and without collision bodies), and an untrained
solver for one."""

import torch

from ikdp.chain_arm import ChainArm
from ikdp.denoisers import DenoiserConfig
from ikdp.model import IKDiffusion, ModelConfig
from ikdp.priors import PosePrior
from ikdp.schedule import ScheduleConfig
from ikdp.solver import Solver
from ikdp.tree_arm import TreeArm
from ikdp.urdf import parse_chain

# a waist joint shared by two arms of two joints each, every axis different, and a fixed hand at each end
TWO_ARMS_URDF = """<robot name="two_arms">
  <link name="base"/><link name="torso"/>
  <link name="l1"/><link name="l2"/><link name="left_hand"/>
  <link name="r1"/><link name="r2"/><link name="right_hand"/>
  <joint name="waist" type="revolute"><parent link="base"/><child link="torso"/>
    <origin xyz="0 0 0.3"/><axis xyz="0 0 1"/><limit lower="-1.5" upper="1.5"/></joint>
  <joint name="left_shoulder" type="revolute"><parent link="torso"/><child link="l1"/>
    <origin xyz="0 0.2 0.1" rpy="0.3 0 0"/><axis xyz="0 1 0"/><limit lower="-2" upper="2"/></joint>
  <joint name="left_elbow" type="revolute"><parent link="l1"/><child link="l2"/>
    <origin xyz="0.25 0 0"/><axis xyz="1 0 0"/><limit lower="-2" upper="2"/></joint>
  <joint name="left_wrist" type="continuous"><parent link="l2"/><child link="left_hand"/>
    <origin xyz="0.2 0 0"/><axis xyz="0 0 1"/></joint>
  <joint name="right_shoulder" type="revolute"><parent link="torso"/><child link="r1"/>
    <origin xyz="0 -0.2 0.1" rpy="-0.3 0 0"/><axis xyz="0 1 0"/><limit lower="-2" upper="2"/></joint>
  <joint name="right_elbow" type="revolute"><parent link="r1"/><child link="r2"/>
    <origin xyz="0.25 0 0"/><axis xyz="1 0 0"/><limit lower="-2" upper="2"/></joint>
  <joint name="right_hand_joint" type="fixed"><parent link="r2"/><child link="right_hand"/>
    <origin xyz="0.2 0 0" rpy="0 0.5 0"/></joint>
</robot>"""


def two_arms(target: str = "pose") -> TreeArm:
    chains = [
        ChainArm.from_description(parse_chain(TWO_ARMS_URDF, hand), target=target)
        for hand in ("left_hand", "right_hand")
    ]
    return TreeArm(chains, target=target)


def untrained_solver(arm: TreeArm) -> Solver:
    torch.manual_seed(0)
    config = ModelConfig(
        representation="joints",
        prediction="sample",
        schedule=ScheduleConfig(timesteps=8, kind="karras"),
        denoiser=DenoiserConfig(kind="chain_film", hidden=48, blocks=1, dls_skip=True, limit_aware_step=True),
        arm=arm.to_config(),
    )
    return Solver(IKDiffusion(config), PosePrior("uniform"), {})


# the same shape with bodies: a torso box, two forearm boxes and two round hands that swing in one horizontal
# plane, through the torso and through each other
BODIES_URDF = """<robot name="two_arms_bodies">
  <link name="base"/>
  <link name="torso">
    <collision><origin xyz="0 0 0.25"/><geometry><box size="0.12 0.2 0.3"/></geometry></collision></link>
  <link name="l1"><collision><origin xyz="0.1 0 0"/><geometry><box size="0.2 0.04 0.04"/></geometry></collision></link>
  <link name="left_hand"><collision><geometry><sphere radius="0.03"/></geometry></collision></link>
  <link name="r1"><collision><origin xyz="0.1 0 0"/><geometry><box size="0.2 0.04 0.04"/></geometry></collision></link>
  <link name="right_hand"><collision><geometry><sphere radius="0.03"/></geometry></collision></link>
  <joint name="waist" type="revolute"><parent link="base"/><child link="torso"/>
    <origin xyz="0 0 0.1"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="10" velocity="1"/></joint>
  <joint name="left_shoulder" type="revolute"><parent link="torso"/><child link="l1"/>
    <origin xyz="0 0.16 0.35"/><axis xyz="0 0 1"/><limit lower="-2.5" upper="2.5" effort="10" velocity="1"/></joint>
  <joint name="left_elbow" type="revolute"><parent link="l1"/><child link="left_hand"/>
    <origin xyz="0.22 0 0"/><axis xyz="0 0 1"/><limit lower="-2.5" upper="2.5" effort="10" velocity="1"/></joint>
  <joint name="right_shoulder" type="revolute"><parent link="torso"/><child link="r1"/>
    <origin xyz="0 -0.16 0.35"/><axis xyz="0 0 1"/><limit lower="-2.5" upper="2.5" effort="10" velocity="1"/></joint>
  <joint name="right_elbow" type="revolute"><parent link="r1"/><child link="right_hand"/>
    <origin xyz="0.22 0 0"/><axis xyz="0 0 1"/><limit lower="-2.5" upper="2.5" effort="10" velocity="1"/></joint>
</robot>"""
