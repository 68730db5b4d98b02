difference() { cylinder(r=123.80, h=1.2, $fn=360); translate([0, 0, -1]) cylinder(r=111.80, h=5, $fn=360); }
