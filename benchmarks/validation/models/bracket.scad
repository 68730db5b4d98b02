// L bracket with two holes and a fillet rib
difference() {
  union() {
    cube([30, 16, 3]);
    cube([3, 16, 18]);
    translate([3, 7, 3]) rotate([90, 0, 0]) linear_extrude(height = 2, center = false)
      polygon([[0, 0], [10, 0], [0, 10]]);
  }
  translate([18, 8, -1]) cylinder(h = 5, r = 2.5, $fn = 40);
  translate([-1, 8, 11]) rotate([0, 90, 0]) cylinder(h = 5, r = 2.5, $fn = 40);
}
