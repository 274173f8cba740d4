"""A tree's sphere cover, and which of its links can meet one another.

The cover is its chains' own (ikdp/link_spheres.py), each link once: a link on several chains (the
G1's torso) from the first chain that has it, and a link off every chain (a leg, the head, a hand's
fingers) from the chain it hangs nearest to (fewest joints between), so that it moves with the tree
joint that really carries it rather than with a copy of another arm held still.

Links that can meet are the pairs on different branches: each link moves with the set of chains it
lies on (the torso with both arms, a hand with its own arm; a hanging link with its parent's), and
two links whose sets differ move relative to one another through joints the other lacks (a hand
against the torso, the thighs or the other hand). Left out: pairs next to each other in a chain
(a shoulder on the torso) and pairs whose spheres already overlap at the zero pose (held within the
limits): the fitted spheres are fatter than the meshes, and where they touch at rest they touch
always, which would push every pose.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace

import torch

from ikdp.link_spheres import LinkSpheres, SphereCover, sphere_cover


def tree_sphere_cover(tree) -> SphereCover:
    """The chains' covers merged onto `tree.link_names`, each link once (the module's rule)."""
    index = {name: position for position, name in enumerate(tree.link_names)}
    indices, centers, radii, covered = [], [], [], set()
    hanging: dict[str, object] = {}
    for chain in tree.chains:
        cover = sphere_cover(chain)
        own = cover.chain
        mine = {chain.link_names[link] for link in own.link_indices} - covered
        for link, center, radius in zip(own.link_indices, own.centers, own.radii, strict=True):
            if chain.link_names[link] in mine:
                indices.append(index[chain.link_names[link]])
                centers.append(center)
                radii.append(radius)
        covered |= mine
        for item in cover.hanging:
            if item.link in index:
                continue  # on another chain: that chain's links cover it, moving with its joints
            placed = replace(item, parent=index[chain.link_names[item.parent]])
            if item.link not in hanging or len(item.joints) < len(hanging[item.link].joints):
                hanging[item.link] = placed
    return SphereCover(LinkSpheres(tuple(indices), tuple(centers), tuple(radii)), tuple(hanging.values()))


def tree_link_spheres(tree, held_joints: Mapping | None = None) -> LinkSpheres:
    """Every sphere of the tree in its link's frame (an index into `tree.link_names`); the joints off every chain
    held at `held_joints`, the others at zero (within their limits): a humanoid's legs stand straight, where a
    chain's default, the end of each range farthest from zero (a gripper open), would raise them."""
    cover = tree_sphere_cover(tree)
    rest = {
        name: 0.0 if joint.lower is None else min(max(0.0, joint.lower), joint.upper)
        for name, joint in cover.held_joints.items()
        if joint.mimic is None
    }
    cover.held_values(held_joints)  # refuses an unknown joint or a value outside its limits, naming it
    return cover.posed({**rest, **dict(held_joints or {})})


def branches(tree) -> list[frozenset[int]]:
    """Each link of `tree.link_names`: the chains it lies on (what moves it)."""
    return [
        frozenset(number for number, chain in enumerate(tree.chains) if name in chain.link_names)
        for name in tree.link_names
    ]


def adjacent_links(tree) -> set[frozenset[int]]:
    """Pairs of links next to each other on some chain, as indices into `tree.link_names`."""
    index = {name: position for position, name in enumerate(tree.link_names)}
    pairs = set()
    for chain in tree.chains:
        names = chain.link_names
        pairs |= {frozenset((index[a], index[b])) for a, b in zip(names[:-1], names[1:], strict=True)}
    return pairs


def meeting_pairs(tree, spheres: LinkSpheres) -> torch.Tensor:
    """(P, 2) the sphere pairs checked for self-collision: on different branches, not adjacent, and not
    overlapping at the zero pose (held within the limits)."""
    sets, adjacent = branches(tree), adjacent_links(tree)
    links = torch.tensor(spheres.link_indices)
    first, second = torch.triu_indices(len(links), len(links), offset=1)
    apart = torch.tensor(
        [
            sets[a] != sets[b] and frozenset((a, b)) not in adjacent
            for a, b in zip(links[first].tolist(), links[second].tolist(), strict=True)
        ],
        dtype=torch.bool,
    )
    first, second = first[apart], second[apart]
    limits = tree.joint_limits.double()
    rest = torch.zeros(tree.num_joints, dtype=torch.float64).clamp(limits[:, 0], limits[:, 1])
    centers = spheres.world_centers(tree, rest)  # (S, 3)
    radii = spheres.radii_like(centers)
    touching = (centers[first] - centers[second]).norm(dim=-1) < radii[first] + radii[second]
    # a link pair touching at rest is left out whole: its other spheres sit a few millimetres from contact
    touching_links = zip(links[first[touching]].tolist(), links[second[touching]].tolist(), strict=True)
    resting = {frozenset(pair) for pair in touching_links}
    keep = torch.tensor(
        [frozenset((a, b)) not in resting for a, b in zip(links[first].tolist(), links[second].tolist(), strict=True)],
        dtype=torch.bool,
    )
    return torch.stack([first[keep], second[keep]], dim=-1)
