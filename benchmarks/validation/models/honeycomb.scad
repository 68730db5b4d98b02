// honeycomb panel: a 36 x 30 x 5 mm plate with a grid of hexagonal holes (1.2 mm webs)
difference() {
  translate([-18, -15, 0]) cube([36, 30, 5]);
  for (i = [-3:3], j = [-2:2])
    translate([i * 5.2, j * 6 + (i % 2 == 0 ? 0 : 3), -1]) cylinder(h = 7, r = 2.3, $fn = 6);
}
