// Test part of the post-processing tests (flowtwin): a tube on a square foot, 24 x 24 x 8 mm.
// Perimeters, solid and sparse infill, travels and retractions in ~40 layers.
difference() {
    union() {
        translate([-12, -12, 0]) cube([24, 24, 1.2]);
        cylinder(h = 8, r = 9, $fn = 64);
    }
    translate([0, 0, -1]) cylinder(h = 12, r = 5, $fn = 48);
}
