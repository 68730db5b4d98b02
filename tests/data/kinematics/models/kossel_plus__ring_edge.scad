difference() { cylinder(r=133.18, h=1.2, $fn=360); translate([0, 0, -1]) cylinder(r=123.68, h=5, $fn=360); }
