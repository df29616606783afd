"""Whole robots: the rigid-body model of a robot (URDF or DH, through Pinocchio) identified jointly with each
joint's friction from multi-joint motion (issue 24). Layer 1: arrays in, estimates out."""
from .description import Robot, load_robot
from .identify import RobotFit, identify_robot

__all__ = ["Robot", "RobotFit", "identify_robot", "load_robot"]
