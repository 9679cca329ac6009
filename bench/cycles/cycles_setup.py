# What render_obj.py and bake_glb.py set up alike in Blender's Cycles: sirad's materials (a
# diffuse BSDF of the reflectance, emission of that radiance, optionally a black back), the
# converged settings (a black world, 64 diffuse bounces, nothing clamped, no denoising nor
# adaptive sampling, the Standard view) and how finely an emitter is cut for area sampling
# (render_obj.py's top says why).
import math

import bpy


def material(name, kd, ke, black_back=False):
    """A material of reflectance kd and emitted radiance ke; with black_back its back side is
    black and absorbing, as the back of a one-sided face in sirad's model."""
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    nt = m.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    diffuse = nt.nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (*kd, 1.0)
    surface = diffuse.outputs[0]
    if max(ke) > 0:
        emission = nt.nodes.new("ShaderNodeEmission")
        emission.inputs["Color"].default_value = (*ke, 1.0)
        emission.inputs["Strength"].default_value = 1.0
        add = nt.nodes.new("ShaderNodeAddShader")
        nt.links.new(emission.outputs[0], add.inputs[0])
        nt.links.new(diffuse.outputs[0], add.inputs[1])
        surface = add.outputs[0]
    if black_back:
        black = nt.nodes.new("ShaderNodeBsdfDiffuse")
        black.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
        geometry = nt.nodes.new("ShaderNodeNewGeometry")
        mix = nt.nodes.new("ShaderNodeMixShader")
        nt.links.new(geometry.outputs["Backfacing"], mix.inputs[0])
        nt.links.new(surface, mix.inputs[1])
        nt.links.new(black.outputs[0], mix.inputs[2])
        surface = mix.outputs[0]
    nt.links.new(surface, out.inputs["Surface"])
    return m


def converged(scene, spp, seed):
    """Cycles on the CPU set up for a converged reference of sirad's model."""
    scene.world = bpy.data.worlds.new("black")
    scene.world.use_nodes = True
    scene.world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    scene.render.engine = "CYCLES"
    cy = scene.cycles
    cy.device = "CPU"
    cy.samples = spp
    cy.use_adaptive_sampling = False
    cy.use_denoising = False
    cy.seed = seed
    cy.max_bounces = 64
    cy.diffuse_bounces = 64
    cy.glossy_bounces = 0
    cy.transmission_bounces = 0
    cy.volume_bounces = 0
    cy.transparent_max_bounces = 0
    cy.caustics_reflective = False
    cy.caustics_refractive = False
    cy.sample_clamp_direct = 0.0
    cy.sample_clamp_indirect = 0.0
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0


def area_sampling_cuts(longest, twice_area):
    """The N for which Cycles samples each of a face's N x N pieces by area, the scene scaled to
    an extent of 1: longest edge x twice the area <= 1e-4 per piece."""
    return max(1, math.ceil((longest * twice_area / 1e-4) ** (1 / 3)))
